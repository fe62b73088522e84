"""Bounded fuzzing of the studio's readers: anything but a StudioError is a failure.

Runs the g2o, TUM, ``inter_agent_lc.dat`` and synth-JSON readers, and ``read_multi_g2o`` on a folder,
on inputs that hypothesis generates (records built from hostile tokens, arbitrary bytes, JSON
documents) and on mutations of valid files (byte flips, insertions, deletions, cuts, swapped lines,
hostile tokens put in place of good ones), for a given time budget::

    python -m tests.fuzz.fuzz_readers --seconds 60

Every input goes through the reader as a file (so the encoding and size checks run too). A reader
that returns or raises a :class:`~studio.core.errors.StudioError` with a one-line message passes; any other
exception, a message over several lines, or a warning (numpy's ``RuntimeWarning`` would be printed
beside the CLI's one line) is a failure, printed with its input. The run ends with the number of
inputs tried per reader and the failures; the exit code is 1 when there were failures.
"""

from __future__ import annotations

import argparse
import copy
import json
import random
import shutil
import sys
import tempfile
import time
import traceback
import warnings
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from studio.core.errors import StudioError

__all__ = ["FuzzReport", "fuzz", "READERS", "main"]

DATA = Path(__file__).resolve().parent.parent / "data"

# Tokens that have broken parsers before: specials, overflows, signs, separators, other scripts.
HOSTILE_TOKENS = [
    "nan",
    "NaN",
    "-nan",
    "inf",
    "-inf",
    "Infinity",
    "1e400",
    "-1e400",
    "1e308",
    "1e-320",
    "0",
    "-0",
    "-0.0",
    "9223372036854775807",
    "9223372036854775808",
    "-9223372036854775809",
    "99999999999999999999999",
    "1" * 400,
    "0x10",
    "1_000",
    "١٢",
    "+",
    "-",
    ".",
    "e5",
    "1e",
    "0.0.0",
    "",
    "#",
    "\x00",
    "\ufeff",
    "é",
    "\u2028",
    "\t",
    "\r",
    "VERTEX_SE2",
    "EDGE_SE3:QUAT",
    "1.5",
    "-3",
    "2147483648",
    "1e-300",
    "1e300",
]

_G2O_SEED = (DATA / "golden" / "tiny_single" / "agent1" / "posegraph.g2o").read_bytes()
_GT_SEED = (DATA / "golden" / "tiny_single" / "agent1" / "agent1_GT.tum").read_bytes()
_TUM_SEED = (DATA / "trajectories" / "alpha.tum").read_bytes()
_G2O_SE2_SEED = (
    b"VERTEX_SE2 0 0 0 0\nVERTEX_SE2 1 1 0 0.1\nVERTEX_SE2 2 2 0.1 0.2\n"
    b"EDGE_SE2 0 1 1 0 0.1 100 0 0 100 0 1000\nEDGE_SE2 1 2 1 0.1 0.1 100 0 0 100 0 1000\n"
    b"EDGE_SE2 0 2 2 0.1 0.2 100 0 0 100 0 1000\n"
)
_DAT_SEED = (
    b"1 0 2 3 0.5 -0.25 0.0 0.0 0.0 0.1 0.994987 100 0.0 0.0 0.0 0.0 0.0 100 0.0 0.0 0.0 0.0 100 "
    b"0.0 0.0 0.0 400 0.0 0.0 400 0.0 400\n"
    b"2 1 1 0 0.5 -0.25 0.0 0.0 0.0 0.0 1.0 100 0.0 0.0 0.0 0.0 0.0 100 0.0 0.0 0.0 0.0 100 "
    b"0.0 0.0 0.0 400 0.0 0.0 400 0.0 400\n"
)
_JSON_SEED = (DATA / "configs" / "tiny_single.json").read_bytes()


def _seed_dataset(folder: Path) -> None:
    """A valid two-agent multi-g2o folder: two copies of the tiny golden agent and two closures."""
    for name in ("agent1", "agent2"):
        (folder / name).mkdir(parents=True)
        (folder / name / "posegraph.g2o").write_bytes(_G2O_SEED)
        (folder / name / f"{name}_GT.tum").write_bytes(_GT_SEED)
    (folder / "inter_agent_lc.dat").write_bytes(_DAT_SEED)


# --------------------------------------------------------------------------------------- mutations


def mutate(data: bytes, rng: random.Random, rounds: int | None = None) -> bytes:
    """A few random edits of ``data``: byte flips, insertions, deletions, cuts, hostile tokens,
    duplicated, swapped or dropped lines."""
    buf = bytearray(data)
    for _ in range(rounds if rounds is not None else rng.randint(1, 4)):
        op = rng.randrange(9)
        n = len(buf)
        if op == 0 and n:  # flip a byte
            buf[rng.randrange(n)] = rng.randrange(256)
        elif op == 1:  # insert random bytes
            k = rng.randrange(n + 1)
            buf[k:k] = bytes(rng.randrange(256) for _ in range(rng.randint(1, 8)))
        elif op == 2 and n:  # delete a run
            k = rng.randrange(n)
            del buf[k : k + rng.randint(1, 32)]
        elif op == 3 and n:  # cut the file (a truncated write)
            del buf[rng.randrange(n) :]
        elif op in (4, 5):  # a token replaced by a hostile one
            lines = bytes(buf).split(b"\n")
            li = rng.randrange(len(lines))
            toks = lines[li].split(b" ")
            ti = rng.randrange(len(toks))
            toks[ti] = rng.choice(HOSTILE_TOKENS).encode("utf-8")
            lines[li] = b" ".join(toks)
            buf = bytearray(b"\n".join(lines))
        elif op == 6:  # duplicate, drop or swap lines
            lines = bytes(buf).split(b"\n")
            i, j = rng.randrange(len(lines)), rng.randrange(len(lines))
            choice = rng.randrange(3)
            if choice == 0:
                lines.insert(j, lines[i])
            elif choice == 1 and len(lines) > 1:
                del lines[i]
            else:
                lines[i], lines[j] = lines[j], lines[i]
            buf = bytearray(b"\n".join(lines))
        elif op == 7:  # a token dropped or added (wrong column counts)
            lines = bytes(buf).split(b"\n")
            li = rng.randrange(len(lines))
            toks = lines[li].split(b" ")
            if rng.random() < 0.5 and len(toks) > 1:
                del toks[rng.randrange(len(toks))]
            else:
                toks.insert(rng.randrange(len(toks) + 1), rng.choice([b"0", b"1.5", b"-2", b"x"]))
            lines[li] = b" ".join(toks)
            buf = bytearray(b"\n".join(lines))
        elif op == 8:  # another encoding or line ending
            text = bytes(buf).decode("utf-8", errors="replace")
            buf = bytearray(
                rng.choice(
                    [
                        lambda t: t.encode("utf-16"),
                        lambda t: t.encode("latin-1", errors="replace"),
                        lambda t: t.replace("\n", "\r\n").encode(),
                        lambda t: t.replace("\n", "\r").encode(),
                        lambda t: b"\xef\xbb\xbf" + t.encode(),
                    ]
                )(text)
            )
    return bytes(buf)


def mutate_json(data: bytes, rng: random.Random) -> bytes:
    """Structural edits of a JSON config (values replaced by hostile ones, keys dropped or nested),
    then sometimes byte-level edits."""
    try:
        doc = json.loads(data)
    except ValueError:
        return mutate(data, rng)

    def paths_of(node, path, out):
        items = node.items() if isinstance(node, dict) else enumerate(node) if isinstance(node, list) else ()
        for k, v in items:
            out.append(path + [k])
            paths_of(v, path + [k], out)
        return out

    hostile = [
        None,
        True,
        0,
        -1,
        1e308,
        -1e308,
        5e-324,
        10**400,
        2**31,
        2**63,
        -(2**31) - 1,
        "x",
        "",
        [],
        {},
        [[[[]]]],
        1e-300,
        1e300,
        2**31 - 1,
        0.5,
        3,
        "1",
        "NaN",
    ]
    for _ in range(rng.randint(1, 3)):
        paths = paths_of(doc, [], [])
        if not paths:
            break
        path = rng.choice(paths)
        parent = doc
        for p in path[:-1]:
            parent = parent[p]
        if rng.random() < 0.15 and isinstance(parent, dict):
            parent.pop(path[-1], None)
        else:
            parent[path[-1]] = copy.deepcopy(rng.choice(hostile))  # no shared (or cyclic) containers
    text = json.dumps(doc, indent=rng.choice([None, 1, 4]))
    if rng.random() < 0.1:
        text = text.replace('"NaN"', "NaN").replace("1e+308", "1e999")
    out = text.encode("utf-8")
    return mutate(out, rng) if rng.random() < 0.3 else out


# ------------------------------------------------------------------------------------- generators

tokens = st.sampled_from(HOSTILE_TOKENS) | st.from_regex(r"-?[0-9]{1,3}(\.[0-9]{1,4})?(e-?[0-9]{1,3})?", fullmatch=True)


def _record(tag: str, width: int):
    return st.lists(tokens, min_size=max(0, width - 2), max_size=width + 2).map(lambda ts: " ".join([tag, *ts]))


g2o_texts = st.lists(
    _record("VERTEX_SE2", 4)
    | _record("EDGE_SE2", 11)
    | _record("VERTEX_SE3:QUAT", 8)
    | _record("EDGE_SE3:QUAT", 30)
    | st.sampled_from(["", "# comment", "FIX 0", "VERTEX_XY 0 1 2"]),
    max_size=12,
).map("\n".join)
tum_texts = st.lists(
    st.lists(tokens, min_size=6, max_size=10).map(" ".join)
    | st.sampled_from(["", "# t x y z qx qy qz qw", "timestamp,x,y,z,qx,qy,qz,qw"]),
    max_size=12,
).map("\n".join)
dat_texts = st.lists(st.lists(tokens, min_size=11, max_size=34).map(" ".join), max_size=6).map("\n".join)
json_values = st.recursive(
    st.none() | st.booleans() | st.integers(-(2**70), 2**70) | st.floats() | st.text(max_size=6),
    lambda kids: st.lists(kids, max_size=4) | st.dictionaries(st.text(max_size=8), kids, max_size=4),
    max_leaves=25,
)
json_texts = json_values.map(lambda v: json.dumps(v, allow_nan=True))


# ------------------------------------------------------------------------------------------ readers


def _read_g2o(path: Path) -> None:
    from studio.io.g2o import read_g2o

    read_g2o(path)
    read_g2o(path, edges=False)


def _read_tum(path: Path) -> None:
    from studio.io.tum import read_tum, read_tum_rows

    read_tum(path)
    read_tum_rows(path)


def _read_dat(path: Path) -> None:
    from studio.core.model import PoseKind
    from studio.io.inter_lc_dat import read_inter_lc_dat

    read_inter_lc_dat(path)
    read_inter_lc_dat(path, PoseKind.SE2)


def _read_json(path: Path) -> None:
    from studio.io.synth_config import read_synth_config

    read_synth_config(path, warn=lambda msg: None)


@dataclass(frozen=True)
class Target:
    name: str
    read: Callable[[Path], None]
    seeds: tuple[bytes, ...]
    generated: st.SearchStrategy
    json: bool = False


READERS: dict[str, Target] = {
    "g2o": Target("g2o", _read_g2o, (_G2O_SEED, _G2O_SE2_SEED), g2o_texts),
    "tum": Target("tum", _read_tum, (_TUM_SEED, _GT_SEED), tum_texts),
    "inter_lc_dat": Target("inter_lc_dat", _read_dat, (_DAT_SEED,), dat_texts),
    "synth_json": Target("synth_json", _read_json, (_JSON_SEED,), json_texts, json=True),
}
MULTI = "multi_g2o"


@dataclass
class Failure:
    reader: str
    error: str
    where: str
    data: bytes | dict[str, bytes]


@dataclass
class FuzzReport:
    tried: dict[str, int] = field(default_factory=dict)
    failures: list[Failure] = field(default_factory=list)
    seconds: float = 0.0

    @property
    def distinct(self) -> dict[tuple[str, str], Failure]:
        out: dict[tuple[str, str], Failure] = {}
        for f in self.failures:
            out.setdefault((f.reader, f.where), f)
        return out


def _check(report: FuzzReport, reader: str, call: Callable[[], None], data) -> None:
    report.tried[reader] = report.tried.get(reader, 0) + 1
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("error")  # a warning would print beside the CLI's one line
            call()
    except StudioError as err:
        if "\n" in str(err) or not str(err):
            report.failures.append(
                Failure(reader, f"{type(err).__name__} over several lines: {str(err)!r}", "multi-line message", data)
            )
    except BaseException as err:  # noqa: BLE001 - everything else is what we hunt for
        if isinstance(err, KeyboardInterrupt):
            raise
        tb = traceback.extract_tb(err.__traceback__)
        last = next(
            (
                fr
                for fr in reversed(tb)
                if "/studio/" in fr.filename or "/converters/" in fr.filename or "/generator/" in fr.filename
            ),
            tb[-1] if tb else None,
        )
        where = f"{type(err).__name__} at {Path(last.filename).name}:{last.lineno}" if last else type(err).__name__
        report.failures.append(Failure(reader, f"{type(err).__name__}: {str(err)[:200]}", where, data))


def _run_file(report: FuzzReport, target: Target, data: bytes, work: Path) -> None:
    path = work / ("c.json" if target.json else "f.txt")
    path.write_bytes(data)
    _check(report, target.name, lambda: target.read(path), data)


def _run_multi(report: FuzzReport, files: dict[str, bytes], work: Path) -> None:
    from studio.io.multig2o import read_multi_g2o

    folder = work / "ds"
    shutil.rmtree(folder, ignore_errors=True)
    _seed_dataset(folder)
    for rel, data in files.items():
        (folder / rel).write_bytes(data)

    def call() -> None:
        read_multi_g2o(folder)
        read_multi_g2o(folder, edges=False)

    _check(report, MULTI, call, files)


def _hypothesis_round(report: FuzzReport, target: Target, work: Path, examples: int, stop: float) -> None:
    """``examples`` generated inputs (hypothesis is only the generator: nothing is shrunk)."""

    @settings(
        max_examples=examples, deadline=None, database=None, derandomize=False, suppress_health_check=list(HealthCheck)
    )
    @given(text=target.generated | st.binary(max_size=300).map(lambda b: b.decode("latin-1")))
    def run(text: str) -> None:
        if time.monotonic() < stop:
            _run_file(report, target, text.encode("utf-8", errors="surrogatepass"), work)

    run()


def fuzz(
    seconds: float,
    *,
    seed: int | None = None,
    readers: list[str] | None = None,
    log: Callable[[str], None] | None = None,
) -> FuzzReport:
    """Fuzz every reader (or those named) for about ``seconds`` in total, round-robin.

    The first round always runs, with plain mutations, so every reader is tried at least once even
    when the machine is too busy for the time budget (a hypothesis round may spend it all starting).
    """
    names = readers or [*READERS, MULTI]
    rng = random.Random(seed)
    report = FuzzReport(tried={n: 0 for n in names})
    t0 = time.monotonic()
    stop = t0 + seconds
    work = Path(tempfile.mkdtemp(prefix="studio-fuzz-"))
    try:
        k = 0
        while k < len(names) or time.monotonic() < stop:
            if log is not None and k and k % len(names) == 0:
                log(
                    f"\r{time.monotonic() - t0:6.1f} s: {sum(report.tried.values())} inputs, "
                    f"{len(report.failures)} failures"
                )
            name = names[k % len(names)]
            k += 1
            if name == MULTI:
                for _ in range(20):
                    rel = rng.choice(["agent1/posegraph.g2o", "agent2/agent2_GT.tum", "inter_agent_lc.dat"])
                    seed_data = {
                        "agent1/posegraph.g2o": _G2O_SEED,
                        "agent2/agent2_GT.tum": _GT_SEED,
                        "inter_agent_lc.dat": _DAT_SEED,
                    }[rel]
                    _run_multi(report, {rel: mutate(seed_data, rng)}, work)
                continue
            target = READERS[name]
            if k > len(names) and rng.random() < 0.35:
                _hypothesis_round(report, target, work, 30, stop)
            else:
                for _ in range(30):
                    seed_data = rng.choice(target.seeds)
                    data = mutate_json(seed_data, rng) if target.json else mutate(seed_data, rng)
                    _run_file(report, target, data, work)
    finally:
        shutil.rmtree(work, ignore_errors=True)
    report.seconds = time.monotonic() - t0
    return report


def _show(data) -> str:
    if isinstance(data, dict):
        return "; ".join(f"{k}: {_show(v)}" for k, v in data.items())
    return repr(data[:600]) + (f" ... ({len(data)} bytes)" if len(data) > 600 else "")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--seconds", type=float, default=60.0, help="Time budget in seconds (default 60).")
    parser.add_argument("--seed", type=int, default=None, help="Seed of the mutations (default: random).")
    parser.add_argument(
        "--reader", action="append", choices=[*READERS, MULTI], help="Only this reader (repeatable; default: all)."
    )
    args = parser.parse_args(argv)
    report = fuzz(
        args.seconds, seed=args.seed, readers=args.reader, log=lambda m: print(m, end="", file=sys.stderr, flush=True)
    )
    print(file=sys.stderr)
    total = sum(report.tried.values())
    print(
        f"{total} inputs in {report.seconds:.0f} s; {len(report.failures)} failures ({len(report.distinct)} distinct)"
    )
    for name, n in report.tried.items():
        print(f"  {name}: {n} inputs")
    for (reader, where), f in report.distinct.items():
        print(f"FAILURE {reader}: {f.error} [{where}]\n  input: {_show(f.data)}")
    return 1 if report.failures else 0


if __name__ == "__main__":
    sys.exit(main())
