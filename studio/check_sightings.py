"""``studio check``'s part for range-bearing sightings (``range_bearing.txt``, MR.CLAM's robot-to-robot
measurements): their residuals at the ground truth of the keyframes they are tied to.

For each sighting, the range and bearing the ground truth predicts (from the observer's keyframe to
the observed agent's keyframe, in the plane) are compared with the measured ones; each residual is
divided by the sighting's standard deviation and the squares summed: chi2 per degree of freedom for
the range, the bearing and both (two degrees of freedom per sighting), with the verdict
``studio check`` gives an edge class. The keyframes are the ones nearest in time to the sighting, so
the robots' motion between the keyframe and the sighting's time (``*_offset_ns``) is part of the
residual: the check judges the file as a solver would use it. Sightings whose residual is beyond 3
sigma are counted (misidentified robots, or far offsets); the chi2 without them is given too.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np

from studio.core.errors import FormatError
from studio.core.geometry import normalize_angle, se3_poses_to_planar
from studio.io.range_bearing import RANGE_BEARING_NAME, read_range_bearing

__all__ = ["RangeBearingCheck", "check_range_bearing", "format_range_bearing_check"]


@dataclass(frozen=True)
class RangeBearingCheck:
    sightings: int
    chi2_per_dof: float
    range_chi2_per_dof: float
    bearing_chi2_per_dof: float
    verdict: str
    beyond_3_sigma: int
    chi2_per_dof_within_3_sigma: float
    verdict_within_3_sigma: str
    median_keyframe_offset_s: float

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)


def _verdict(chi2: float, dof: int) -> str:
    from studio.check import verdict

    return verdict(chi2, dof)


def check_range_bearing(folder: Path, truth: Sequence[np.ndarray]) -> RangeBearingCheck | None:
    """The sightings of ``folder/range_bearing.txt`` at ``truth`` (each agent's keyframe ground
    truth, planar rows or 3D rows), or None where the dataset has no such file."""
    path = folder / RANGE_BEARING_NAME
    if not path.is_file():
        return None
    sizes = [len(t) for t in truth]
    rb = read_range_bearing(path)
    for side in ("observer", "observed"):
        agent, index = getattr(rb, f"{side}_agent"), getattr(rb, f"{side}_index")
        known = agent < len(sizes)
        known[known] = index[known] < np.asarray(sizes, dtype=np.int64)[agent[known]]
        if not known.all():
            k = int(np.flatnonzero(~known)[0])
            raise FormatError(
                f"{path}: sighting {k + 1}: agent {int(agent[k]) + 1} vertex {int(index[k])} is not in the dataset"
            )
    planar = [t if t.shape[1] == 3 else se3_poses_to_planar(t) for t in truth]
    offsets = np.concatenate([[0], np.cumsum(sizes)])
    stacked = np.concatenate(planar)
    obs = stacked[offsets[rb.observer_agent] + rb.observer_index]
    tgt = stacked[offsets[rb.observed_agent] + rb.observed_index]
    d = tgt[:, 0:2] - obs[:, 0:2]
    e_r = (rb.range_m - np.hypot(d[:, 0], d[:, 1])) / rb.sigma_range_m
    e_b = normalize_angle(rb.bearing_rad - (np.arctan2(d[:, 1], d[:, 0]) - obs[:, 2])) / rb.sigma_bearing_rad
    n = len(rb)
    total = e_r**2 + e_b**2
    inside = (np.abs(e_r) <= 3) & (np.abs(e_b) <= 3)
    k = int(inside.sum())
    chi2_in = float(total[inside].sum())
    offs = np.abs(np.concatenate([rb.observer_offset_ns, rb.observed_offset_ns])) / 1e9
    return RangeBearingCheck(
        n,
        float(total.sum()) / (2 * n) if n else math.nan,
        float((e_r**2).sum()) / n if n else math.nan,
        float((e_b**2).sum()) / n if n else math.nan,
        _verdict(float(total.sum()), 2 * n),
        n - k,
        chi2_in / (2 * k) if k else math.nan,
        _verdict(chi2_in, 2 * k),
        float(np.median(offs)) if n else 0.0,
    )


def format_range_bearing_check(c: RangeBearingCheck | None) -> list[str]:
    """Lines for ``studio check``'s table."""
    if c is None:
        return []
    return [
        "",
        f"range-bearing sightings: {c.sightings} at their keyframes' ground truth (median keyframe offset "
        f"{c.median_keyframe_offset_s:.3g} s): chi2/dof {c.chi2_per_dof:.4g} (range {c.range_chi2_per_dof:.4g}, "
        f"bearing {c.bearing_chi2_per_dof:.4g}), {c.verdict}",
        f"  {c.beyond_3_sigma} beyond 3 sigma; the rest: chi2/dof {c.chi2_per_dof_within_3_sigma:.4g}, "
        f"{c.verdict_within_3_sigma}",
    ]
