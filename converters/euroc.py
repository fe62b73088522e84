"""EuRoC MAV sequences (e.g. MH_01_easy .. MH_05_difficult) as agents in one frame, as the COVINS
and CCM-SLAM collaborative benchmarks use them.

A sequence's ground truth is ``<sequence>/mav0/state_groundtruth_estimate0/data.csv``: a ``#``
header, then ``timestamp [ns], p_RS_R_x, p_RS_R_y, p_RS_R_z [m], q_RS_w, q_RS_x, q_RS_y, q_RS_z,
v_RS_R (3), b_w_RS_S (3), b_a_RS_S (3)``: 17 comma-separated columns, **nanosecond** stamps and the
quaternion **scalar first** (``w x y z``). The machine-hall sequences share one world frame (the
Leica/Vicon frame), so their trajectories are agents of one map. Inputs are sequence folders (or
their ``mav0`` folder, or the ``data.csv`` files themselves); each agent is named after its
sequence folder (``mh_01_easy``).

**TUM VI** sequences (``dataset-room1_512_16``) ship the same ASL layout with motion-capture ground
truth instead: ``<sequence>/mav0/mocap0/data.csv``, a ``#`` header, then ``timestamp [ns],
p_RS_R_x, p_RS_R_y, p_RS_R_z [m], q_RS_w, q_RS_x, q_RS_y, q_RS_z``: 8 columns, the same nanosecond
stamps and scalar-first quaternion, the pose of the IMU in the motion-capture frame. Where a
sequence folder has both, the state estimate (EuRoC's) is taken.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

from studio.converters.names import safe_agent_name
from studio.converters.text import read_table
from studio.core.errors import ConfigError, FormatError
from studio.core.trajectory import Trajectory, Warn, clean_trajectory
from studio.core.types import PathLike

__all__ = ["read_euroc", "euroc_ground_truth", "GT_RELATIVE"]

GT_RELATIVE = Path("mav0") / "state_groundtruth_estimate0" / "data.csv"
#: TUM VI's ground truth: motion capture of the IMU, 8 columns
MOCAP_RELATIVE = Path("mav0") / "mocap0" / "data.csv"
_EUROC_WHAT = "EuRoC ground truth: timestamp [ns], p xyz [m], q wxyz, v xyz, b_w xyz, b_a xyz"
_MOCAP_WHAT = "TUM VI mocap: timestamp [ns], p xyz [m], q wxyz"
#: columns and layout by the folder holding the data.csv (a bare data.csv may be either)
_LAYOUTS: dict[str, tuple[int | tuple[int, ...], str]] = {
    "state_groundtruth_estimate0": (17, _EUROC_WHAT),
    "mocap0": (8, _MOCAP_WHAT),
}
_GROUND_TRUTH_FOLDERS = tuple(_LAYOUTS)


def euroc_ground_truth(path: Path) -> tuple[str, Path] | None:
    """``(agent name, data.csv)`` of a sequence folder, its ``mav0`` folder or the file; or None."""
    if path.is_file() and path.name == "data.csv":
        seq = path.parent.parent.parent if path.parent.name in _GROUND_TRUTH_FOLDERS else path.parent
        return safe_agent_name(seq.name.lower()), path
    for full in (GT_RELATIVE, MOCAP_RELATIVE):
        for base, rel in ((path, full), (path, Path(*full.parts[1:]))):
            if (base / rel).is_file():
                seq = base if rel == full else base.parent
                return safe_agent_name(seq.name.lower()), base / rel
    return None


def read_euroc(
    inputs: Sequence[PathLike],
    *,
    agents: Sequence[str] = (),
    warn: Warn | None = None,
    progress: object = None,
) -> list[Trajectory]:
    """``studio convert euroc SEQ...``: one agent per sequence, in the order given."""
    out = []
    for raw in inputs:
        found = euroc_ground_truth(Path(raw))
        if found is None:
            raise FormatError(f"{raw}: no EuRoC ground truth ({GT_RELATIVE})")
        name, csv = found
        columns, what = _LAYOUTS.get(csv.parent.name, ((17, 8), f"{_EUROC_WHAT}; or {_MOCAP_WHAT}"))
        table, stamps = read_table(csv, columns, what=what, int_first=True, quaternion="wxyz")
        assert stamps is not None
        quat_xyzw = table[:, [5, 6, 7, 4]]  # w x y z in the file
        out.append(clean_trajectory(name, stamps, table[:, 1:4], quat_xyzw, str(csv), warn))
    names = [t.name for t in out]
    for n in names:
        if names.count(n) > 1:
            raise ConfigError(f"two EuRoC inputs would both be agent {n!r}")
    return out
