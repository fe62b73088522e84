"""The ``"studio"`` block of a kollagen JSON config: read, validate and write
:class:`~studio.generator.extensions.StudioExtensions`.

Unlike kollagen's own keys (unknown ones are ignored with a warning, as kollagen ignores them), an
unknown key inside the block is refused with the closest known key and its JSON path: the block is
the studio's own, versioned (``"version": 1``), so a misspelling would silently change a dataset.

::

    "studio": {"version": 1, "walk": "grid3d",
               "grid3d": {"vertical_probability": 0.1, "vertical_step": 1.0, "tilt_std_dev": 0.0},
               "noise": {"odometry": {"model": "student_t", "dof": 5},
                         "inter": {"model": "mixture", "weights": [0.9, 0.1], "scales": [1, 10]}},
               "outliers": {"intra_fraction": 0.05, "inter_fraction": 0.05,
                            "kinds": {"random": 0.5, "aliasing": 0.5}, "seed": 1},
               "information_frame": "measurement"}
"""

from __future__ import annotations

import difflib
import math
from collections.abc import Callable
from dataclasses import fields
from typing import Any

from studio.core.errors import ConfigError
from studio.core.units import MAX_MAGNITUDE as _LIMIT  # the one bound of every number
from studio.generator.extended import WALK_MODES, walk_mode
from studio.generator.extensions import (
    EXTENSIONS_VERSION,
    INFORMATION_FRAMES,
    NOISE_CLASSES,
    NOISE_MODELS,
    OUTLIER_KINDS,
    Grid3dConfig,
    NoiseModel,
    OutlierConfig,
    StudioExtensions,
)

__all__ = ["parse_studio_block", "studio_block_to_json"]

Fail = Callable[[str, str], ConfigError]
_TOP = ("version", "walk", "grid3d", "noise", "outliers", "information_frame")
_MODEL_KEYS = {
    "gaussian": ("model",),
    "student_t": ("model", "dof"),
    "laplace": ("model",),
    "mixture": ("model", "weights", "scales"),
}


def _check_keys(obj: Any, path: str, known: tuple[str, ...], fail: Fail) -> dict[str, Any]:
    if not isinstance(obj, dict):
        raise fail(path, "must be a JSON object")
    for key in obj:
        if key not in known:
            close = difflib.get_close_matches(key, known, n=1)
            hint = f"did you mean {close[0]!r}?" if close else f"known keys: {', '.join(known)}"
            raise fail(f"{path}.{key}", f"unknown key in the studio block ({hint})")
    return obj


def _number(
    obj: dict[str, Any], key: str, path: str, fail: Fail, default: float, lo: float, hi: float, *, open_lo: bool = False
) -> float:
    if key not in obj:
        return default
    v = obj[key]
    p = f"{path}.{key}"
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(float(v)):
        raise fail(p, "must be a finite number")
    v = float(v)
    if v < lo or v > hi or (open_lo and v == lo):
        raise fail(p, f"{v!r} is outside {'(' if open_lo else '['}{lo!r}, {hi!r}]")
    return v


def _choice(obj: dict[str, Any], key: str, path: str, fail: Fail, default: str, choices: tuple[str, ...]) -> str:
    if key not in obj:
        return default
    v: str = obj[key]
    if v not in choices:
        raise fail(f"{path}.{key}", f"must be one of {', '.join(choices)}, got {v!r}")
    return v


def _noise_model(obj: Any, path: str, fail: Fail) -> NoiseModel:
    if not isinstance(obj, dict):
        raise fail(path, 'must be a JSON object such as {"model": "laplace"}')
    if "model" not in obj:
        raise fail(f"{path}.model", f"missing key (one of {', '.join(NOISE_MODELS)})")
    model = _choice(obj, "model", path, fail, "gaussian", NOISE_MODELS)
    _check_keys(obj, path, _MODEL_KEYS[model], fail)
    if model == "student_t":
        if "dof" not in obj:
            raise fail(f"{path}.dof", "missing key (degrees of freedom, over 2 so the variance is finite)")
        dof = _number(obj, "dof", path, fail, 0.0, 2.0, _LIMIT, open_lo=True)
        return NoiseModel("student_t", dof=dof)
    if model == "mixture":
        lists = []
        for key in ("weights", "scales"):
            v = obj.get(key)
            if (
                not isinstance(v, list)
                or not v
                or any(
                    isinstance(x, bool)
                    or not isinstance(x, (int, float))
                    or not math.isfinite(x)
                    or not 0 < x <= _LIMIT
                    for x in v
                )
            ):
                raise fail(f"{path}.{key}", "must be a non-empty array of positive numbers")
            lists.append(tuple(float(x) for x in v))
        if len(lists[0]) != len(lists[1]):
            raise fail(f"{path}.scales", f"has {len(lists[1])} entries for {len(lists[0])} weights")
        total = sum(lists[0])
        return NoiseModel("mixture", weights=tuple(w / total for w in lists[0]), scales=lists[1])
    return NoiseModel(model)


def parse_studio_block(obj: Any, *, fail: Fail, exact: bool) -> StudioExtensions:
    """Validate the block; ``fail(json_path, message)`` builds the error (file and path in its message)."""
    _check_keys(obj, "studio", _TOP, fail)
    if "version" not in obj:
        raise fail("studio.version", f"missing key (this studio reads version {EXTENSIONS_VERSION})")
    if obj["version"] != EXTENSIONS_VERSION or isinstance(obj["version"], bool):
        raise fail("studio.version", f"{obj['version']!r} is not a version this studio reads ({EXTENSIONS_VERSION})")
    walk = _choice(obj, "walk", "studio", fail, "kollagen", tuple(WALK_MODES))
    mode = walk_mode(walk)
    for other in WALK_MODES.values():  # a mode's own options apply to that mode only
        if other.block is not None and other.block != mode.block and obj.get(other.block):
            raise fail(f"studio.{other.block}", f'applies to walk "{other.name}" only')
    g = _check_keys(obj.get("grid3d", {}), "studio.grid3d", tuple(f.name for f in fields(Grid3dConfig)), fail)
    d = Grid3dConfig()
    seed_offset = g.get("seed_offset", 0)
    if isinstance(seed_offset, bool) or not isinstance(seed_offset, int) or abs(seed_offset) > 2**31:
        raise fail("studio.grid3d.seed_offset", "must be an integer")
    grid3d = Grid3dConfig(
        vertical_probability=_number(g, "vertical_probability", "studio.grid3d", fail, d.vertical_probability, 0, 1),
        vertical_step=_number(g, "vertical_step", "studio.grid3d", fail, d.vertical_step, 0, _LIMIT, open_lo=True),
        tilt_std_dev=_number(g, "tilt_std_dev", "studio.grid3d", fail, d.tilt_std_dev, 0, 1.0),
        seed_offset=seed_offset,
    )
    if not mode.planar and exact:
        raise fail(
            "exact_information_matrix",
            f'kollagen\'s Exact information is planar; walk "{walk}" writes '
            "its own consistent 6x6 information (set it to false)",
        )
    n = _check_keys(obj.get("noise", {}), "studio.noise", NOISE_CLASSES, fail)
    noise = tuple((c, _noise_model(n[c], f"studio.noise.{c}", fail)) for c in NOISE_CLASSES if c in n)
    outliers = None
    if "outliers" in obj:
        o = _check_keys(obj["outliers"], "studio.outliers", tuple(f.name for f in fields(OutlierConfig)), fail)
        od = OutlierConfig()
        p = "studio.outliers"
        kinds = od.kinds
        if "kinds" in o:
            k = _check_keys(o["kinds"], f"{p}.kinds", OUTLIER_KINDS, fail)
            kinds = tuple(
                (name, _number(k, name, f"{p}.kinds", fail, 0.0, 0, _LIMIT)) for name in OUTLIER_KINDS if name in k
            )
            if not any(w > 0 for _, w in kinds):
                raise fail(f"{p}.kinds", "needs a positive weight for random or aliasing")
        seed = o.get("seed", 0)
        if isinstance(seed, bool) or not isinstance(seed, int) or abs(seed) > 2**63:
            raise fail(f"{p}.seed", "must be an integer")
        window = o.get("aliasing_window", od.aliasing_window)
        if isinstance(window, bool) or not isinstance(window, int) or not 1 <= window <= 5:
            raise fail(f"{p}.aliasing_window", "must be an integer in 1..5 (steps)")
        rmax = _number(o, "random_radius", p, fail, od.random_radius, 0, _LIMIT, open_lo=True)
        rmin = _number(o, "random_min_radius", p, fail, od.random_min_radius, 0, _LIMIT)
        if rmin >= rmax:
            raise fail(f"{p}.random_min_radius", f"{rmin!r} must be under random_radius ({rmax!r})")
        outliers = OutlierConfig(
            intra_fraction=_number(o, "intra_fraction", p, fail, 0.0, 0, 1),
            inter_fraction=_number(o, "inter_fraction", p, fail, 0.0, 0, 1),
            kinds=kinds,
            random_radius=rmax,
            random_min_radius=rmin,
            aliasing_min_distance=_number(o, "aliasing_min_distance", p, fail, od.aliasing_min_distance, 0, _LIMIT),
            aliasing_window=window,
            seed=seed,
        )
    frame = _choice(obj, "information_frame", "studio", fail, "kollagen", INFORMATION_FRAMES)
    if frame == "measurement" and not exact:
        raise fail(
            "studio.information_frame",
            '"measurement" rotates kollagen\'s Exact odometry information: it needs "exact_information_matrix": true',
        )
    return StudioExtensions(
        version=EXTENSIONS_VERSION, walk=walk, grid3d=grid3d, noise=noise, outliers=outliers, information_frame=frame
    )


def studio_block_to_json(ext: StudioExtensions) -> dict[str, Any]:
    """The block as written in the effective config (every key, defaults included)."""
    out: dict[str, Any] = {"version": ext.version, "walk": ext.walk}
    if walk_mode(ext.walk).block == "grid3d":
        out["grid3d"] = {f.name: getattr(ext.grid3d, f.name) for f in fields(Grid3dConfig)}
    if ext.noise:
        noise = {}
        for cls, m in ext.noise:
            entry: dict[str, Any] = {"model": m.model}
            if m.model == "student_t":
                entry["dof"] = m.dof
            if m.model == "mixture":
                entry["weights"], entry["scales"] = list(m.weights), list(m.scales)
            noise[cls] = entry
        out["noise"] = noise
    if ext.outliers is not None:
        o = {f.name: getattr(ext.outliers, f.name) for f in fields(OutlierConfig)}
        o["kinds"] = dict(ext.outliers.kinds)
        out["outliers"] = o
    out["information_frame"] = ext.information_frame
    return out
