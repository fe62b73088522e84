"""Spec files of ``studio bench`` and ``studio sweep``: TOML (or JSON for ``.json``), read into a
plain mapping with one-line errors naming the file (and line, where the parser gives one)."""

from __future__ import annotations

import json
import re
import sys
from pathlib import Path
from typing import Any

from studio.core.errors import ConfigError, FormatError
from studio.core.types import PathLike
from studio.io.input_files import read_input_bytes
from studio.io.strict_json import unique_keys

if sys.version_info >= (3, 11):
    import tomllib
else:  # Python 3.10: the same parser, as a package
    import tomli as tomllib

__all__ = ["read_spec_file", "check_spec_keys"]

#: Larger spec files are refused before reading (a spec is a few kB).
MAX_SPEC_BYTES = 4 * 1024 * 1024
#: Deepest nesting of arrays and tables a spec may have (a spec needs 3 or 4; the parsers recurse).
MAX_SPEC_DEPTH = 64
_STRINGS = re.compile(r'"(?:[^"\\\n]|\\.)*"|\'[^\'\n]*\'')


def _nesting_depth(text: str) -> int:
    """The deepest nesting of ``[ {`` outside quoted strings (counted on the bytes, no recursion)."""
    import numpy as np

    data = np.frombuffer(_STRINGS.sub('""', text).encode("utf-8"), dtype=np.uint8)
    steps = np.zeros(len(data), dtype=np.int64)
    steps[(data == ord("[")) | (data == ord("{"))] = 1
    steps[(data == ord("]")) | (data == ord("}"))] = -1
    return int(np.cumsum(steps).max(initial=0))


def read_spec_file(path: PathLike, *, what: str = "spec") -> Any:
    path = Path(path)
    if not path.exists():
        raise ConfigError(f"{path}: no such {what} file")
    try:
        if path.stat().st_size > MAX_SPEC_BYTES:
            raise ConfigError(f"{path}: larger than {MAX_SPEC_BYTES >> 20} MiB; not a {what}")
        try:
            text = read_input_bytes(path).decode("utf-8")  # a FIFO or device: refused, never waited on
        except FormatError as err:
            raise ConfigError(str(err)) from None
        depth = _nesting_depth(text)
        if depth > MAX_SPEC_DEPTH:
            raise ConfigError(f"{path}: nested {depth} deep, over the limit of {MAX_SPEC_DEPTH}; not a {what}")
        return json.loads(text, object_pairs_hook=unique_keys) if path.suffix == ".json" else tomllib.loads(text)
    except RecursionError:
        raise ConfigError(f"{path}: nested too deeply; not a {what}") from None
    except UnicodeDecodeError as err:
        raise ConfigError(f"{path}: not UTF-8 text (byte {err.start})") from None
    except json.JSONDecodeError as err:
        raise ConfigError(f"{path}:{err.lineno}: not valid JSON ({err.msg})") from None
    except tomllib.TOMLDecodeError as err:
        raise ConfigError(f"{path}: not valid TOML ({err})") from None
    except ValueError as err:  # a key given twice (unique_keys)
        raise ConfigError(f"{path}: not valid JSON ({err})") from None
    except OSError as err:
        raise ConfigError(f"{path}: cannot read ({err.strerror})") from None


def check_spec_keys(data: Any, known: set[str], source: str, what: str) -> None:
    """``data`` must be a table whose keys are all ``known``: else one line naming ``source``, the
    key and the closest known key."""
    import difflib
    from collections.abc import Mapping

    if not isinstance(data, Mapping):
        raise ConfigError(f"{source}: a {what} is a table of keys ({', '.join(sorted(known))})")
    for key in data:
        if key not in known:
            hint = difflib.get_close_matches(str(key), sorted(known), n=1)
            raise ConfigError(
                f"{source}: {key}: unknown key"
                + (f" (did you mean {hint[0]!r}?)" if hint else "")
                + f"; known: {', '.join(sorted(known))}"
            )
