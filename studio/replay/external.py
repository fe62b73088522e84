"""``command:PROGRAM ARGS``: a replay back-end in another process, in any language, speaking the
protocol of :mod:`studio.replay.protocol` as JSON lines over its standard input and output.

The studio writes one line per message to the program's standard input and reads one line back per
``checkpoint`` and ``end`` (docs/replay.md, "Back-ends in other languages", has the schema):

* ``{"type": "start", ...}``: the team, the pose layout, the links (no answer);
* ``{"type": "checkpoint", ...}``: the news; the answer: ``{"own": [[vertex, pose...], ...],
  "kept": [[robot, vertex, pose...], ...] or null, "messages": [...], "bytes": [...]}``;
* ``{"type": "end"}``: the end; the same answer, the final beliefs; then standard input closes.

Each answer must come within the time limit (``studio replay --time-limit``, per checkpoint). A
program that ends, hangs or answers what the schema does not allow ends the replay with one
:class:`~studio.core.errors.BackendError` line naming the back-end, the checkpoint and the reason (the
program's last line on standard error when it died); the program is killed and nothing is written.
"""

from __future__ import annotations

import json
import os
import selectors
import shlex
import subprocess
import tempfile
import time
import weakref
from collections.abc import Callable
from typing import Any, BinaryIO

import numpy as np

from studio.core.comms import robot_pairs
from studio.core.errors import BackendError, ConfigError
from studio.replay.protocol import Checkpoint, KeptPoses, ReplayBackend, Setup, Step

__all__ = ["PROTOCOL_VERSION", "DEFAULT_TIME_LIMIT_S", "ExternalBackend", "command_backend"]

PROTOCOL_VERSION = 1
#: Seconds a program may take to answer one checkpoint (and the end) by default.
DEFAULT_TIME_LIMIT_S = 60.0
#: The longest answer line read: a full estimate of a paper-size dataset is a few MB.
_MAX_LINE_BYTES = 1 << 30
_LAYOUT = {3: ["x", "y", "theta"], 7: ["x", "y", "z", "qx", "qy", "qz", "qw"]}


def command_backend(command: str, time_limit_s: float = DEFAULT_TIME_LIMIT_S) -> Callable[[Setup], ReplayBackend]:
    """The factory of ``command:COMMAND`` (split as a POSIX shell would, run without a shell)."""
    try:
        argv = shlex.split(command)
    except ValueError as err:
        raise ConfigError(f"backend command:{command}: {err}") from None
    if not argv:
        raise ConfigError("backend command: give the program to run, e.g. command:'./my-backend --fast'")

    def factory(setup: Setup) -> ReplayBackend:
        return ExternalBackend(setup, argv, time_limit_s=time_limit_s)

    return factory


def _kill(proc: subprocess.Popen[bytes]) -> None:
    if proc.poll() is None:
        proc.kill()
        proc.wait()


class ExternalBackend:
    """A program behind ``command:``, driven through the protocol (module doc)."""

    def __init__(self, setup: Setup, argv: list[str], *, time_limit_s: float = DEFAULT_TIME_LIMIT_S) -> None:
        self.setup = setup
        self.name = "command:" + shlex.join(argv)
        self.time_limit_s = time_limit_s
        self.own = setup.problem.initial.copy()
        self.links = len(robot_pairs(setup.num_robots))
        self._stderr: BinaryIO = tempfile.TemporaryFile()
        try:
            self.proc = subprocess.Popen(argv, stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=self._stderr)
        except OSError as err:
            raise BackendError(f"backend {self.name}: cannot start {argv[0]}: {err.strerror or err}") from None
        weakref.finalize(self, _kill, self.proc)
        self._buffer = b""
        self._where = "start"
        kind = setup.problem.kind
        self._send(
            {
                "type": "start",
                "protocol": PROTOCOL_VERSION,
                "num_robots": setup.num_robots,
                "num_vertices": setup.problem.num_vertices,
                "pose_kind": kind.value,
                "pose_layout": _LAYOUT[kind.pose_width],
                "links": robot_pairs(setup.num_robots).tolist(),
                "pose_bytes": setup.pose_bytes,
                "edge_bytes": setup.edge_bytes,
            },
            answer=False,
        )

    def advance(self, news: Checkpoint) -> Step:
        self._where = f"checkpoint at tick {news.tick}"
        p, agent = self.setup.problem, self.setup.agent_of_vertex

        def edges(ids: np.ndarray, stamps: np.ndarray) -> list[dict[str, Any]]:
            return [
                {
                    "edge": int(e),
                    "from": int(p.edge_from[e]),
                    "to": int(p.edge_to[e]),
                    "robots": [int(agent[p.edge_from[e]]), int(agent[p.edge_to[e]])],
                    "stamp_ns": int(s),
                    "measurement": p.measurements[e].tolist(),
                    "information_upper": p.information_upper[e].tolist(),
                }
                for e, s in zip(ids.tolist(), stamps.tolist())
            ]

        request = {
            "type": "checkpoint",
            "tick": news.tick,
            "time_ns": news.time_ns,
            "poses": [
                {"vertex": v, "robot": int(agent[v]), "stamp_ns": int(s), "initial": p.initial[v].tolist()}
                for v, s in zip(news.vertices.tolist(), news.vertex_ns.tolist())
            ],
            "measurements": edges(news.edges, news.edge_ns),
            "closures": edges(news.closures, news.closure_ns),
            "groups": [list(g) for g in news.groups],
            "contacts": np.asarray(news.contacts).tolist(),
        }
        return self._send(request)

    def finish(self) -> Step:
        self._where = "end"
        step = self._send({"type": "end"})
        assert self.proc.stdin is not None
        self.proc.stdin.close()
        try:
            self.proc.wait(timeout=self.time_limit_s)
        except subprocess.TimeoutExpired:
            _kill(self.proc)
        return step

    def _fail(self, reason: str) -> BackendError:
        _kill(self.proc)
        return BackendError(f"backend {self.name}: {self._where}: {reason}")

    def _send(self, message: dict[str, Any], *, answer: bool = True) -> Step:
        t0 = time.perf_counter()
        line = self._exchange((json.dumps(message, separators=(",", ":")) + "\n").encode(), answer=answer)
        if not answer:
            return Step(self.own.copy(), 0.0, np.zeros(self.links, np.int64), np.zeros(self.links, np.int64))
        return self._parse(line, time.perf_counter() - t0)

    def _died(self) -> BackendError:
        code = self.proc.wait()
        self._stderr.seek(0)
        last = [x for x in self._stderr.read().decode(errors="replace").splitlines() if x.strip()]
        said = f" ({last[-1].strip()[:200]})" if last else ""
        return self._fail(f"the program ended with exit code {code} before answering{said}")

    def _exchange(self, request: bytes, *, answer: bool) -> bytes:
        """Write ``request``, then (``answer``) read one line, both within the time limit."""
        assert self.proc.stdin is not None and self.proc.stdout is not None
        deadline = time.monotonic() + self.time_limit_s
        out, fd_in, fd_out = memoryview(request), self.proc.stdin.fileno(), self.proc.stdout.fileno()
        os.set_blocking(fd_in, False)
        with selectors.DefaultSelector() as sel:
            sel.register(fd_in, selectors.EVENT_WRITE)
            if answer:
                sel.register(fd_out, selectors.EVENT_READ)
            while out or (answer and b"\n" not in self._buffer):
                remaining = deadline - time.monotonic()
                if remaining <= 0:
                    raise self._fail(f"no answer within the time limit of {self.time_limit_s:g} s")
                for key, _ in sel.select(remaining):
                    if key.fd == fd_in:
                        try:
                            out = out[os.write(fd_in, out[: 1 << 16]) :]
                        except BrokenPipeError:
                            raise self._died() from None
                        if not out:
                            sel.unregister(fd_in)
                    else:
                        chunk = os.read(fd_out, 1 << 20)
                        if not chunk:
                            raise self._died()
                        self._buffer += chunk
                        if len(self._buffer) > _MAX_LINE_BYTES:
                            raise self._fail(f"an answer longer than {_MAX_LINE_BYTES} bytes")
        line, _, self._buffer = self._buffer.partition(b"\n")
        return line

    def _parse(self, line: bytes, seconds: float) -> Step:
        """The answer line as a Step; BackendError naming what breaks the schema."""
        try:
            answer = json.loads(line)
        except (ValueError, UnicodeDecodeError):
            shown = line[:60].decode(errors="replace")
            raise self._fail(f"the answer is not one JSON object: {shown!r}") from None
        if not isinstance(answer, dict):
            raise self._fail(f"the answer is not one JSON object: {type(answer).__name__}")
        w, n = self.setup.problem.kind.pose_width, self.setup.problem.num_vertices
        own = self._rows(answer, "own", 1 + w)
        if own is not None and len(own):
            vertex = self._ids(own[:, 0], n, "own", "vertex")
            self.own[vertex] = own[:, 1:]
        kept_rows = self._rows(answer, "kept", 2 + w)
        kept = None
        if kept_rows is not None:
            robot = self._ids(kept_rows[:, 0], self.setup.num_robots, "kept", "robot")
            vertex = self._ids(kept_rows[:, 1], n, "kept", "vertex")
            if (self.setup.agent_of_vertex[vertex] == robot).any():
                raise self._fail('"kept": a robot keeps one of its own poses (those go in "own")')
            kept = KeptPoses(robot, vertex, kept_rows[:, 2:].copy())
        counts = [self._counts(answer, key) for key in ("messages", "bytes")]
        return Step(self.own.copy(), seconds, counts[0], counts[1], kept)

    def _rows(self, answer: dict[str, Any], key: str, width: int) -> np.ndarray | None:
        value = answer.get(key)
        if value is None:
            if key == "own":
                raise self._fail('the answer has no "own"')
            return None
        try:
            rows = np.asarray(value, dtype=np.float64).reshape(-1, width)
        except (TypeError, ValueError):
            raise self._fail(f'"{key}": expected rows of {width} numbers') from None
        if not np.isfinite(rows).all():
            raise self._fail(f'"{key}": a value is not a finite number')
        return rows

    def _ids(self, column: np.ndarray, bound: int, key: str, what: str) -> np.ndarray:
        ids = column.astype(np.int64)
        if (ids != column).any() or (ids < 0).any() or (ids >= bound).any():
            raise self._fail(f'"{key}": a {what} id is not an integer in 0..{bound - 1}')
        return ids

    def _counts(self, answer: dict[str, Any], key: str) -> np.ndarray:
        value = answer.get(key)
        ok = isinstance(value, list) and len(value) == self.links
        ok = ok and all(isinstance(v, int) and not isinstance(v, bool) and v >= 0 for v in value)  # type: ignore[union-attr]
        if not ok:
            raise self._fail(f'"{key}": expected {self.links} counts (one per link), non-negative integers')
        return np.asarray(value, dtype=np.int64)
