"""Strict JSON out: every JSON the studio writes or prints (results, reports, tables, configs) is
standard JSON, never ``NaN`` or ``Infinity``. A non-finite number is refused in one line that names
the output and the value's JSON path, before anything is written."""

from __future__ import annotations

import json
import math
from typing import Any

from studio.core.errors import OutputError

__all__ = ["dumps_strict", "non_finite_path", "unique_keys"]


def non_finite_path(obj: Any, path: str = "$") -> tuple[str, float] | None:
    """The JSON path (``$.runs[0].ape_m``) and value of the first non-finite float in ``obj``, or None."""
    if isinstance(obj, float):
        return None if math.isfinite(obj) else (path, obj)
    if isinstance(obj, dict):
        items: Any = ((f"{path}.{key}", value) for key, value in obj.items())
    elif isinstance(obj, (list, tuple)):
        items = ((f"{path}[{k}]", value) for k, value in enumerate(obj))
    elif hasattr(obj, "dtype") and hasattr(obj, "tolist"):  # a numpy number or array
        return non_finite_path(obj.tolist(), path)
    else:
        return None
    for where, value in items:
        found = non_finite_path(value, where)
        if found is not None:
            return found
    return None


def dumps_strict(obj: Any, where: str, **kwargs: Any) -> str:
    """``json.dumps(obj, allow_nan=False, **kwargs)``; a non-finite number is an :class:`OutputError`
    ``<where>: <json path> is nan, not a finite number`` instead (``where``: the file or the option)."""
    try:
        return json.dumps(obj, allow_nan=False, **kwargs)
    except ValueError as err:
        default = kwargs.get("default")
        found = non_finite_path(obj if default is None else json.loads(json.dumps(obj, default=default)))
        if found is None:
            raise OutputError(f"{where}: cannot write JSON ({err})") from None
        path, value = found
        raise OutputError(f"{where}: {path} is {value!r}, not a finite number (strict JSON); nothing written") from None


def unique_keys(pairs: list[tuple[str, Any]]) -> dict[str, Any]:
    """``object_pairs_hook`` for ``json.loads``: an object whose key is given twice is a
    ``ValueError`` (the decoder would keep the last value silently)."""
    out: dict[str, Any] = {}
    for key, value in pairs:
        if key in out:
            raise ValueError(f"the key {key!r} is given twice in one object")
        out[key] = value
    return out
