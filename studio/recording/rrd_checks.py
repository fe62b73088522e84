"""Exact checks of recordings: a content fingerprint read back with Rerun's ``RrdReader``, and
Rerun's own ``rrd verify`` / ``rrd compare`` run as subprocesses.

Every check returns a plain value or raises: :func:`rrd_verify` and :func:`rrd_compare` return
nothing and raise :class:`~studio.core.errors.FormatError` with the tail of Rerun's output (never a
``(bool, str)`` tuple, which is truthy in an ``assert`` whatever it holds).
"""

from __future__ import annotations

import hashlib
import json
import os
import sys
from pathlib import Path
from typing import Any

from studio.core.errors import FormatError
from studio.core.types import PathLike
from studio.runtime.capture import CappedRun, run_capped

__all__ = ["fingerprint_rrd", "read_fingerprint", "write_fingerprint", "rrd_verify", "rrd_compare"]


#: Columns that differ between runs by design: row ids are time-based, and the blueprint's rows carry
#: the wall-clock ``log_time`` of the ``save`` call (the recording itself has no clock values).
_VOLATILE_COLUMNS = ("rerun.controls.RowId", "log_time")

#: One logged row of a column: its index values ``((index name, value), ...)`` and its exact bytes.
_Row = tuple[tuple[tuple[str, int], ...], bytes]

# Rerun's chunk API and the pyarrow columns and fields it hands out carry no type information: they
# are ``Any`` below.


def _column_digest(parts: list[list[_Row]]) -> str:
    """Hash the rows ``(index, value)`` of one column, sorted by index then value."""
    rows = [row for part in parts for row in part]
    rows.sort()
    h = hashlib.sha256()
    for i, v in rows:
        h.update(repr(i).encode())
        h.update(b"\x1f")
        h.update(v)
        h.update(b"\x1e")
    return h.hexdigest()


def _value_bytes(col: Any) -> list[bytes | None]:
    """Exact text per row: JSON of the Python values (floats print with ``repr``, which round-trips,
    so one ulp changes the text), with the arrow type in front; None for a null row."""
    typ = str(col.type).encode() + b"|"
    return [None if v is None else typ + json.dumps(v, sort_keys=True, default=repr).encode() for v in col.to_pylist()]


def _store_digests(chunks: Any, prefix: str) -> dict[str, str]:
    """``{'<prefix> <entity> <component>': sha256}`` over every chunk of one store."""
    groups: dict[str, list[list[_Row]]] = {}
    for chunk in chunks:
        batch = chunk.to_record_batch()
        names = batch.schema.names
        index_names = sorted(n for n in names if _is_index(batch.schema.field(n)) and n not in _VOLATILE_COLUMNS)
        index_cols = [batch.column(n) for n in index_names]
        if index_cols:
            idx = list(
                zip(*[[(name, v) for v in col.cast("int64").to_pylist()] for name, col in zip(index_names, index_cols)])
            )
        else:
            idx = [(("static", 0),)] * batch.num_rows
        for n in names:
            if n in index_names or n in _VOLATILE_COLUMNS or _is_volatile(batch.schema.field(n)):
                continue
            values = _value_bytes(batch.column(n))
            present = [(i, v) for i, v in zip(idx, values) if v is not None]  # null: not logged in that row
            key = f"{prefix} {chunk.entity_path} {n}"
            groups.setdefault(key, []).append(present)
    return {k: _column_digest(v) for k, v in sorted(groups.items())}


def _field_kind(field: Any) -> str:
    md = field.metadata or {}
    kind: str = md.get(b"rerun:kind", b"").decode()
    return kind


def _is_index(field: Any) -> bool:
    return _field_kind(field) in ("index", "time")


def _is_volatile(field: Any) -> bool:
    return _field_kind(field) == "control"


def fingerprint_rrd(path: PathLike) -> dict[str, str]:
    """An exact fingerprint of a recording's content, robust to chunking and row order.

    Keys are ``store entity component`` (plus ``store id``); values are SHA-256 digests of that
    column's (index, value) rows sorted by index, with values as their exact bytes. The blueprint
    store is included. Row ids and chunk ids (time-based) are left out.
    """
    import rerun.chunk as rc

    path = Path(path)
    if not path.is_file():
        raise FormatError(f"{path}: no such recording")
    reader = rc.RrdReader(path)
    out: dict[str, str] = {}
    for label, stores in (("recording", reader.recordings()), ("blueprint", reader.blueprints())):
        for n, store in enumerate(stores):
            prefix = f"{label}{n}"
            if label == "recording":
                out[f"{prefix} id"] = hashlib.sha256(
                    f"{store.application_id}/{store.recording_id}".encode()
                ).hexdigest()
            else:
                out[f"{prefix} id"] = hashlib.sha256(store.application_id.encode()).hexdigest()
            out.update(_store_digests(reader.stream(store=store), prefix))
    return out


def write_fingerprint(fp: dict[str, str], path: PathLike) -> None:
    """One line per key: ``<sha256>  <key>``, sorted, so a diff names what changed."""
    from studio.io.atomic import write_replacing

    text = "".join(f"{v}  {k}\n" for k, v in sorted(fp.items()))
    write_replacing(path, lambda tmp: tmp.write_text(text, encoding="utf-8"))


def read_fingerprint(path: PathLike) -> dict[str, str]:
    out = {}
    for lineno, line in enumerate(Path(path).read_text(encoding="utf-8").splitlines(), start=1):
        if not line.strip():
            continue
        digest, sep, key = line.partition("  ")
        if not sep or len(digest) != 64:
            raise FormatError(f"{path}:{lineno}: expected '<sha256>  <key>'")
        out[key] = digest
    return out


# --------------------------------------------------------------------------------------------------
# Rerun's own checks


def _rerun_cli(*args: str, timeout: float = 300.0) -> CappedRun:
    env = dict(os.environ, RERUN_ANALYTICS="0")
    env.setdefault("CI", "true")
    return run_capped([sys.executable, "-m", "rerun", *args], env=env, timeout_s=timeout)


def _tail(text: str, lines: int = 30, chars: int = 4000) -> str:
    return "\n".join(text.splitlines()[-lines:])[-chars:]


def rrd_verify(path: PathLike) -> None:
    """``rerun rrd verify PATH``; raises :class:`FormatError` (with the tail of Rerun's output) when
    the file does not verify."""
    p = _rerun_cli("rrd", "verify", str(path))
    if p.returncode != 0:
        raise FormatError(f"{path}: rerun rrd verify failed:\n{_tail(p.stdout + p.stderr)}")


def rrd_compare(a: PathLike, b: PathLike) -> None:
    """``rerun rrd compare --unordered A B``; raises :class:`FormatError` (with the tail of Rerun's
    output, which can be huge) when the recordings differ."""
    p = _rerun_cli("rrd", "compare", "--unordered", str(a), str(b))
    if p.returncode != 0:
        raise FormatError(f"{a} and {b} differ (rerun rrd compare):\n{_tail(p.stdout + p.stderr)}")
