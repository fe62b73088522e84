"""File names made from names found in data (agent names, TUM stems, bag topics, spec names).

A name read from a file a user downloaded is not a path: ``../../x`` or ``/home/u/x`` must never
decide where a file is written. :func:`safe_file_name` is the one function every writer uses to turn
such a name into a plain file or folder name.
"""

from __future__ import annotations

import re
from collections.abc import Collection, Iterable

from studio.core.errors import ConfigError, FormatError

__all__ = ["safe_file_name", "safe_file_names", "check_name_component", "MAX_NAME_CHARS"]

#: Longest name made (file systems allow 255 bytes; a suffix such as ``_GT.tum`` is added to it).
MAX_NAME_CHARS = 100
_UNSAFE = re.compile(r"[^A-Za-z0-9_.+-]+")


def safe_file_name(raw: str, *, fallback: str = "agent", reserved: Collection[str] = ()) -> str:
    """A plain file name made from ``raw``: runs of characters other than letters, digits and
    ``_ . + -`` become ``_``, runs of dots too; the result never holds a path separator, never starts
    with a dot (so is never ``.`` or ``..``), is never empty (``fallback``) nor one of ``reserved``
    (then ``<fallback>_<name>``), and has at most :data:`MAX_NAME_CHARS` characters.

    A name that is already safe is returned unchanged, so files named after safe names keep them.
    """
    name = _UNSAFE.sub("_", re.sub(r"\.{2,}", "_", str(raw)))
    name = re.sub(r"_{2,}", "_", name).strip("_").lstrip(".")
    if not name:
        name = fallback
    if name in reserved:
        name = f"{fallback}_{name}"
    return name[:MAX_NAME_CHARS]


def safe_file_names(raws: Iterable[str], *, where: str, fallback: str = "agent") -> list[str]:
    """:func:`safe_file_name` of each name; two names that would share one file are refused
    (``where`` names the data they come from) rather than one file overwriting the other."""
    names: list[str] = []
    seen: dict[str, str] = {}
    for raw in raws:
        name = safe_file_name(raw, fallback=fallback)
        if name in seen:
            raise FormatError(
                f"{where}: the names {seen[name]!r} and {raw!r} give the same file name {name!r}; rename one"
            )
        seen[name] = raw
        names.append(name)
    return names


def check_name_component(raw: object, *, what: str, option: str | None = None) -> str:
    """``raw`` itself when it can name one file or folder inside an output: a non-empty string of at
    most 255 bytes with no path separator, not ``.`` or ``..``, no NUL, no line break and no other
    control character. Otherwise a one-line :class:`ConfigError` naming ``what`` (the option or the
    data field): a name given by a user or found in data never decides where a file goes, and is
    refused rather than silently changed when it is the name the user asked for."""
    if not isinstance(raw, str):
        raise ConfigError(f"{what}: expected a string, got {type(raw).__name__}", option=option)
    rule = None
    if raw in ("", ".", ".."):
        rule = "is empty" if not raw else "is not a file or folder of its own"
    elif "/" in raw or "\\" in raw:
        rule = "holds a path separator" if not raw.startswith("/") else "is an absolute path"
    elif any(ord(c) < 32 or ord(c) == 127 for c in raw):
        rule = "holds a NUL, a line break or another control character"
    elif len(raw.encode("utf-8", "surrogatepass")) > 255:
        rule = "is longer than 255 bytes"
    if rule is not None:
        raise ConfigError(
            f"{what}: {raw!r} {rule}; give one plain file or folder component (no '/', not '..')", option=option
        )
    return raw
