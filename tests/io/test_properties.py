"""Property tests: round trips keep every bit; arbitrary input raises only FormatError."""

from __future__ import annotations

import io

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from studio.core.errors import FormatError
from studio.core.model import InterAgentEdges, PoseKind
from studio.core.trajectory import Trajectory
from studio.io.g2o import G2oDocument, read_g2o, write_g2o
from studio.io.inter_lc_dat import read_inter_lc_dat, write_inter_lc_dat
from studio.io.tum import read_tum, write_tum

finite = st.floats(allow_nan=False, allow_infinity=False, width=64)


def unit_quats(n: int, data) -> np.ndarray:
    q = np.array(data.draw(st.lists(st.tuples(*[st.floats(-1, 1)] * 4), min_size=n, max_size=n)), dtype=float)
    q = q.reshape(n, 4)
    q[np.linalg.norm(q, axis=1) < 1e-3] = [0, 0, 0, 1]
    return q / np.linalg.norm(q, axis=1)[:, None]


@settings(max_examples=400, deadline=None)
@given(data=st.data(), n=st.integers(1, 12), kind=st.sampled_from(list(PoseKind)))
def test_g2o_round_trip_bit_exact(data, n, kind):
    w = kind.pose_width
    poses = np.array(data.draw(st.lists(finite, min_size=n * w, max_size=n * w))).reshape(n, w)
    if kind is PoseKind.SE3:
        poses[:, 3:7] = unit_quats(n, data)
    m = data.draw(st.integers(0, 8)) if n > 1 else 0
    ends = np.array(data.draw(st.lists(st.integers(0, n - 1), min_size=2 * m, max_size=2 * m)), dtype=np.int64)
    ends[m:] = np.where(ends[:m] == ends[m:], (ends[m:] + 1) % n, ends[m:])  # the reader refuses self-loops
    meas = np.array(data.draw(st.lists(finite, min_size=m * w, max_size=m * w))).reshape(m, w)
    if kind is PoseKind.SE3 and m:
        meas[:, 3:7] = unit_quats(m, data)
    iw = kind.information_width
    info = np.array(data.draw(st.lists(finite, min_size=m * iw, max_size=m * iw))).reshape(m, iw)
    ids = np.array(data.draw(st.permutations(range(n))), dtype=np.int64) * 3 - 5
    doc = G2oDocument(
        kind,
        ids,
        poses,
        ids[ends[:m]] if m else ends[:0],
        ids[ends[m:]] if m else ends[:0],
        meas.reshape(m, w),
        info.reshape(m, iw),
    )
    buf = io.StringIO()
    write_g2o(buf, doc)
    back = read_g2o(io.StringIO(buf.getvalue()))
    for f in ("vertex_ids", "vertex_poses", "edge_from", "edge_to", "edge_measurements", "edge_information_upper"):
        assert getattr(back, f).tobytes() == getattr(doc, f).tobytes(), f


@settings(max_examples=400, deadline=None)
@given(data=st.data(), n=st.integers(1, 20))
def test_tum_round_trip_bit_exact(data, n):
    steps = data.draw(st.lists(st.integers(1, 10**12), min_size=n, max_size=n))
    stamps = np.cumsum(np.array(steps, dtype=np.int64)) + data.draw(st.integers(-(10**15), 10**15))
    poses = np.zeros((n, 7))
    poses[:, :3] = np.array(data.draw(st.lists(finite, min_size=3 * n, max_size=3 * n))).reshape(n, 3)
    poses[:, 3:7] = unit_quats(n, data)
    buf = io.StringIO()
    write_tum(buf, Trajectory.from_poses("t", stamps, poses))
    back = read_tum(io.StringIO(buf.getvalue()))
    assert back.stamps_ns.tolist() == stamps.tolist()
    # unit quaternions within 1e-12 of norm 1 are kept as written
    assert back.poses_xyz_quat_xyzw.tobytes() == poses.tobytes()


@settings(max_examples=40, deadline=None)
@given(data=st.data(), n=st.integers(0, 10))
def test_inter_lc_dat_full_precision_round_trip(data, n):
    meas = np.zeros((n, 7))
    meas[:, :3] = np.array(data.draw(st.lists(finite, min_size=3 * n, max_size=3 * n))).reshape(n, 3)
    if n:
        meas[:, 3:7] = unit_quats(n, data)
    info = np.array(data.draw(st.lists(finite, min_size=21 * n, max_size=21 * n))).reshape(n, 21)
    idx = np.array(data.draw(st.lists(st.integers(0, 10**6), min_size=4 * n, max_size=4 * n)), dtype=np.int64).reshape(
        n, 4
    )
    inter = InterAgentEdges(PoseKind.SE3, idx[:, 0], idx[:, 1], idx[:, 2], idx[:, 3], meas, info)
    buf = io.StringIO()
    write_inter_lc_dat(buf, inter, precision="full")
    back = read_inter_lc_dat(io.StringIO(buf.getvalue()))
    for f in ("from_agent", "from_index", "to_agent", "to_index", "measurements", "information_upper"):
        assert getattr(back, f).tobytes() == getattr(inter, f).tobytes(), f


@settings(max_examples=200, deadline=None)
@given(blob=st.binary(max_size=400))
def test_arbitrary_bytes_raise_only_format_errors(tmp_path_factory, blob):
    path = tmp_path_factory.mktemp("fuzz") / "f.txt"
    path.write_bytes(blob)
    for reader in (read_g2o, read_tum, read_inter_lc_dat):
        try:
            reader(path)
        except FormatError as err:
            assert "\n" not in str(err)


record_lines = st.sampled_from(
    [
        "VERTEX_SE2 0 0 0 0",
        "VERTEX_SE2 1 1.5 -2 0.3",
        "EDGE_SE2 0 1 1 0 0 1 0 0 1 0 1",
        "VERTEX_SE3:QUAT 0 0 0 0 0 0 0 1",
        "EDGE_SE3:QUAT 0 1 " + " ".join(["0"] * 6 + ["1"] + ["1"] * 21),
        "0 0 0 0 0 0 0 1",
        "1.5 1 2 3 0 0 0 1",
        "# c",
        "",
        "nan",
        "1e400",
        "VERTEX_SE2 0 x 0 0",
    ]
)


@settings(max_examples=200, deadline=None)
@given(lines=st.lists(record_lines, max_size=8), cut=st.integers(0, 200))
def test_mutated_valid_files_raise_only_format_errors(lines, cut):
    text = "\n".join(lines)
    text = text[: len(text) - cut % (len(text) + 1)]
    for reader in (read_g2o, read_tum, read_inter_lc_dat):
        try:
            reader(io.StringIO(text))
        except FormatError:
            pass
