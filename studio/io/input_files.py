"""Opening an input: every file a command reads is a regular file.

A FIFO given where a file belongs (a rendezvous schedule, a JRL file, a config) blocks a plain
``open`` until something writes to it, forever in practice; a device (``/dev/zero``) never ends; a
folder cannot be read. :func:`read_input_bytes` opens without blocking, looks at what it opened
(``fstat`` of the open file, so nothing can be swapped in between) and refuses anything but a
regular file in one line naming the path, before reading a byte.
"""

from __future__ import annotations

import os
import stat
from pathlib import Path

from studio.core.errors import FormatError
from studio.core.types import PathLike

__all__ = ["read_input_bytes", "check_regular_file", "kind_of"]


def kind_of(mode: int) -> str:
    """What a file of ``mode`` is, in words (``a FIFO``, ``a folder``...)."""
    for test, what in (
        (stat.S_ISDIR, "a folder"),
        (stat.S_ISFIFO, "a FIFO (named pipe)"),
        (stat.S_ISCHR, "a character device"),
        (stat.S_ISBLK, "a block device"),
        (stat.S_ISSOCK, "a socket"),
    ):
        if test(mode):
            return what
    return "not a regular file"


def _refusal(path: PathLike, mode: int) -> FormatError:
    what = kind_of(mode)
    return FormatError(f"{path}: is {what}, not a regular file" if what.startswith("a ") else f"{path}: {what}")


def _limit(limit: int) -> str:
    """``1073741824 byte (1 GiB)``."""
    for shift, unit in ((30, "GiB"), (20, "MiB")):
        if limit and limit % (1 << shift) == 0:
            return f"{limit} byte ({limit >> shift} {unit})"
    return f"{limit} byte"


def check_regular_file(path: PathLike) -> None:
    """Refuse ``path`` unless it is (or links to) a regular file: a missing path, a folder, a FIFO,
    a device or a socket is one :class:`FormatError` line. Does not open it."""
    try:
        mode = os.stat(path).st_mode
    except FileNotFoundError:
        raise FormatError(f"{path}: no such file") from None
    except OSError as err:
        raise FormatError(f"{path}: cannot read ({err.strerror})") from None
    if not stat.S_ISREG(mode):
        raise _refusal(path, mode)


def read_input_bytes(path: PathLike, *, limit: int | None = None, what: str = "inputs") -> bytes:
    """The bytes of the regular file ``path``, at most ``limit`` (larger is refused, from its size
    before reading and again from what was read). A FIFO, device, socket or folder is refused
    without blocking; every failure is one :class:`FormatError` line naming ``path``."""
    path = Path(path)
    try:
        fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK | getattr(os, "O_CLOEXEC", 0))
    except FileNotFoundError:
        raise FormatError(f"{path}: no such file") from None
    except IsADirectoryError:
        raise FormatError(f"{path}: is a folder, not a regular file") from None
    except OSError as err:
        raise FormatError(f"{path}: cannot read ({err.strerror})") from None
    try:
        st = os.fstat(fd)
        if not stat.S_ISREG(st.st_mode):
            raise _refusal(path, st.st_mode)
        if limit is not None and st.st_size > limit:
            raise FormatError(f"{path}: {st.st_size} bytes is over the {_limit(limit)} limit of {what}")
        os.set_blocking(fd, True)
        with os.fdopen(fd, "rb", closefd=False) as f:
            data = f.read() if limit is None else f.read(limit + 1)
    except OSError as err:
        raise FormatError(f"{path}: cannot read ({err.strerror})") from None
    finally:
        os.close(fd)
    if limit is not None and len(data) > limit:
        raise FormatError(f"{path}: over the {_limit(limit)} limit of {what}")
    return data
