"""Atomic outputs: build everything in a staging folder beside the targets, then rename into place.

A run that is interrupted leaves no half-written target. Its staging folder is named
``.studio-staging-<pid>-<name>`` and is removed by the next run in the same parent folder once the
process that made it is gone.
"""

from __future__ import annotations

import contextlib
import os
import shutil
from pathlib import Path
from typing import Callable, Iterator

from studio.core.errors import OutputError

__all__ = ["staged_outputs", "write_replacing", "STAGING_PREFIX"]

STAGING_PREFIX = ".studio-staging-"


def _pid_alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


def _clean_stale(parent: Path) -> None:
    for p in parent.glob(STAGING_PREFIX + "*"):
        pid_text = p.name[len(STAGING_PREFIX):].split("-", 1)[0]
        if pid_text.isdigit() and int(pid_text) != os.getpid() and not _pid_alive(int(pid_text)):
            shutil.rmtree(p, ignore_errors=True)


@contextlib.contextmanager
def staged_outputs(parent: str | os.PathLike, names: list[str], *, force: bool = False) -> Iterator[Path]:
    """Yield a staging folder; on success move ``staging/<name>`` to ``parent/<name>`` for each name.

    Raises :class:`OutputError` before anything is written when a target exists and ``force`` is
    false. Entries of ``names`` that the body did not create are skipped.
    """
    parent = Path(parent)
    for name in names:
        if Path(name).name != name or name in ("", ".", ".."):
            raise OutputError(f"{name!r} is not a plain file or folder name")
    existing = [parent / n for n in names if (parent / n).exists() or (parent / n).is_symlink()]
    if existing and not force:
        raise OutputError(f"{existing[0]} already exists (use --force to overwrite)")
    if parent.exists() and not parent.is_dir():
        raise OutputError(f"{parent} exists and is not a folder")
    try:
        parent.mkdir(parents=True, exist_ok=True)
    except OSError as err:
        raise OutputError(f"{parent}: cannot create folder ({err.strerror})") from None
    _clean_stale(parent)
    staging = parent / f"{STAGING_PREFIX}{os.getpid()}-{names[0]}"
    if staging.exists():
        shutil.rmtree(staging)
    staging.mkdir()
    try:
        yield staging
        trash = staging / ".replaced"
        for name in names:
            src = staging / name
            if not src.exists():
                continue
            dst = parent / name
            if dst.exists() or dst.is_symlink():
                trash.mkdir(exist_ok=True)
                os.replace(dst, trash / name)
            os.replace(src, dst)
    finally:
        shutil.rmtree(staging, ignore_errors=True)


def write_replacing(path: str | os.PathLike, write: Callable[[Path], object]) -> Path:
    """Write one file through ``write(tmp)`` into a temporary file beside ``path``, then rename it
    into place: readers see the old file or the new one, never a half-written one."""
    path = Path(path)
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    try:
        write(tmp)
        os.replace(tmp, path)
    finally:
        tmp.unlink(missing_ok=True)
    return path
