"""The distributed back-ends' formats: studio -> export -> import round trips (jrl, dpgo, symbols),
GTSAM reading the Symbol export, DPGO's split of its g2o, ``studio convert g2o --split``, bad inputs."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from studio.cli import app
from studio.converters.graph_split import GraphImportOptions
from studio.core.geometry import quat_conj, quat_from_rotvec, quat_mul, quat_rotate
from studio.core.model import PoseGraph, PoseKind
from studio.export import export_dataset, read_dataset_outliers
from studio.graph_import import import_graph
from studio.io.dpgo import CSV_HEADER, contiguous_split, isotropic_information, tau_kappa
from studio.io.g2o import G2oDocument, read_g2o, write_g2o
from studio.io.graph_table import graph_edge_table
from studio.io.multig2o import read_multi_g2o
from studio.io.symbol_g2o import symbol_key

DATA = Path(__file__).resolve().parent.parent / "data"
runner = CliRunner()


# ------------------------------------------------------------------------------------ datasets


@pytest.fixture(scope="module")
def datasets(tmp_path_factory) -> dict[str, Path]:
    """A synth dataset, an outlier variant of it and a converted (real-stamp) dataset with outliers."""
    from studio.convert import ConvertConfig, convert
    from studio.converters.build import GraphOptions
    from studio.generator.extensions import OutlierConfig, StudioExtensions
    from studio.synth import load_synth_config, synthesize

    root = tmp_path_factory.mktemp("interop")
    cfg = load_synth_config(DATA / "configs" / "small3x100.json")
    synthesize(cfg, root, rrd=False, jobs=1)
    out_cfg = dataclasses.replace(
        cfg,
        name="small_outliers",
        studio=StudioExtensions(outliers=OutlierConfig(intra_fraction=0.1, inter_fraction=0.1, seed=1)),
    )
    synthesize(out_cfg, root, rrd=False, jobs=1)
    tums = [DATA / "trajectories" / f"{n}.tum" for n in ("alpha", "bob", "carol")]
    convert(ConvertConfig("tum", tums, options=GraphOptions(outlier_fraction=0.1)), root / "converted", rrd=False)
    return {"synth": root / "small3x100", "outliers": root / "small_outliers", "converted": root / "converted"}


def _canonical(graph: PoseGraph):
    t = graph_edge_table(graph)
    rows = t.rows()
    order = np.lexsort(tuple(t.measurements.T[::-1]) + tuple(rows.T[::-1]))
    return rows[order], t.measurements[order], t.information_upper[order]


def _rel(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.max(np.abs(a - b)) / np.max(np.abs(a)))


def _export_import(dataset: Path, fmt: str, tmp_path: Path):
    target = tmp_path / ("x.jrl" if fmt == "jrl" else f"x_{fmt}")
    res = export_dataset(dataset, target, format=fmt)
    source = {"jrl": "jrl", "dpgo": "dpgo", "symbols": "symbols"}[fmt]
    imp = import_graph(source, [target], tmp_path / "back", rrd=False)
    return res, imp, read_multi_g2o(tmp_path / "back")


@pytest.mark.parametrize("which", ["synth", "outliers", "converted"])
@pytest.mark.parametrize("fmt", ["jrl", "symbols", "dpgo"])
def test_export_then_import_gives_the_same_graph(datasets, which, fmt, tmp_path):
    dataset = datasets[which]
    original = read_multi_g2o(dataset)
    labelled = read_dataset_outliers(dataset, original)
    if which != "synth":
        assert len(labelled) > 0
    _, imp, back = _export_import(dataset, fmt, tmp_path)
    assert len(back.agents) == len(original.agents)
    assert back.edge_counts() == original.edge_counts()
    rows0, meas0, info0 = _canonical(original)
    rows1, meas1, info1 = _canonical(back)
    np.testing.assert_array_equal(rows1, rows0)  # ids and which agents each edge joins
    np.testing.assert_array_equal(meas1, meas0)  # measurements bit for bit
    if fmt == "dpgo":
        # DPGO keeps tau and kappa only: the information read back is their isotropic one
        tau, kappa = tau_kappa(PoseKind.SE3, info0)
        assert _rel(isotropic_information(PoseKind.SE3, tau, kappa), info1) <= 1e-12
        tau1, kappa1 = tau_kappa(PoseKind.SE3, info1)
        assert _rel(tau, tau1) <= 1e-12 and _rel(kappa, kappa1) <= 1e-12
    else:
        assert _rel(info0, info1) <= 1e-12
    for a, b in zip(original.agents, back.agents):
        np.testing.assert_array_equal(b.stamps_ns, a.stamps_ns)
        np.testing.assert_array_equal(b.ground_truth, a.ground_truth)
        if fmt != "dpgo":  # DPGO's files hold no vertices: the initial estimate is dead reckoning
            np.testing.assert_array_equal(b.initial, a.initial)
    if fmt == "jrl":
        assert [a.name for a in back.agents] == [a.name for a in original.agents]
    assert {tuple(r) for r in imp.outliers.tolist()} == {tuple(r) for r in labelled.tolist()}
    assert {tuple(r) for r in read_dataset_outliers(tmp_path / "back", back).tolist()} == {
        tuple(r) for r in labelled.tolist()
    }


def test_jrl_layout_follows_jrls_parser(datasets, tmp_path):
    dataset = datasets["outliers"]
    export_dataset(dataset, tmp_path / "o.jrl", format="jrl")
    doc = json.loads((tmp_path / "o.jrl").read_text())
    graph = read_multi_g2o(dataset)
    assert doc["robots"] == [97, 98, 99]  # jrl's Writer writes each char robot id as a number
    first = doc["measurements"]["a"][0]
    assert isinstance(first["stamp"], int) and first["measurements"][0]["type"] == "BetweenFactorPose3"
    factor = first["measurements"][0]
    assert factor["key1"] == symbol_key("a", 0) and factor["key2"] == symbol_key("a", 1)
    assert len(factor["covariance"]) == 36
    # GTSAM's Pose3 order: rotation first, as a rotation vector (the g2o slots' information / 4)
    cov = np.array(factor["covariance"]).reshape(6, 6)
    info = graph.agents[0].odometry.information_upper[0]
    assert np.isclose(1 / cov[3, 3], info[0]) and np.isclose(1 / cov[0, 0], info[15] / 4)
    gt0 = doc["groundtruth"]["a"][0]
    assert gt0["type"] == "Pose3" and gt0["key"] == symbol_key("a", 0)
    qx, qy, qz, qw = graph.agents[0].ground_truth[0, 3:]
    assert gt0["rotation"] == [qw, qx, qy, qz]  # jrl's order: w first
    n_outliers = sum(len(v) for v in doc["outlier_factors"].values())
    assert n_outliers == len(read_dataset_outliers(dataset, graph)) > 0
    potential = {(c, e, m) for c, ids in doc["potential_outlier_factors"].items() for e, m in ids}
    assert {(c, e, m) for c, ids in doc["outlier_factors"].items() for e, m in ids} <= potential
    assert len(potential) >= len(graph.inter)


def test_gtsam_reads_the_symbol_export_with_every_key(datasets, tmp_path):
    gtsam = pytest.importorskip("gtsam")
    dataset = datasets["synth"]
    graph = read_multi_g2o(dataset)
    export_dataset(dataset, tmp_path / "sym", format="symbols")
    factors, values = gtsam.readG2o(str(tmp_path / "sym" / "fullGraph.g2o"), True)
    expected = {int(k) for p, a in zip("abc", graph.agents) for k in symbol_key(p, np.arange(a.num_poses))}
    assert set(values.keys()) == expected
    assert factors.size() == sum(graph.edge_counts().values())
    assert {gtsam.DefaultKeyFormatter(k)[0] for k in values.keys()} == {"a", "b", "c"}
    # robot b's own file: its poses plus the separator poses of its inter-robot edges
    f1, v1 = gtsam.readG2o(str(tmp_path / "sym" / "1.g2o"), True)
    own = {int(k) for k in symbol_key("b", np.arange(graph.agents[1].num_poses))}
    inter_b = (graph.inter.from_agent == 1) | (graph.inter.to_agent == 1)
    assert own <= set(v1.keys())
    assert f1.size() == len(graph.agents[1].odometry) + len(graph.agents[1].loop_closures) + int(inter_b.sum())
    for k in range(f1.size()):
        for key in f1.at(k).keys():
            assert key in set(v1.keys())


def test_dpgo_contiguous_split_has_exactly_the_studios_inter_robot_edges(datasets, tmp_path):
    dataset = datasets["synth"]  # three robots of 401 poses: DPGO's split is the studio's
    graph = read_multi_g2o(dataset)
    res = export_dataset(dataset, tmp_path / "dp", format="dpgo")
    assert not any("contiguous split" in w for w in res.warnings)
    doc = read_g2o(tmp_path / "dp" / "small3x100.g2o", dangling=True)
    assert len(doc.vertex_ids) == 0  # EDGE lines only
    n = int(max(doc.edge_from.max(), doc.edge_to.max())) + 1
    robot = contiguous_split(n, len(graph.agents))  # DPGO: [r*floor(n/R), (r+1)*floor(n/R))
    cut = robot[doc.edge_from] != robot[doc.edge_to]
    starts = np.cumsum([0] + [a.num_poses for a in graph.agents])
    inter = graph.inter
    expected = {
        (int(starts[a] + i), int(starts[b] + j))
        for a, i, b, j in zip(inter.from_agent, inter.from_index, inter.to_agent, inter.to_index)
    }
    assert int(cut.sum()) == len(graph.inter)
    assert set(zip(doc.edge_from[cut].tolist(), doc.edge_to[cut].tolist())) == expected
    header = (tmp_path / "dp" / "robot0" / "measurements.csv").read_text().splitlines()[0]
    assert header == CSV_HEADER


def test_dpgo_warns_where_its_split_differs_and_information_is_lost(datasets, tmp_path):
    res = export_dataset(datasets["converted"], tmp_path / "dp", format="dpgo")
    sizes = [a.num_poses for a in read_multi_g2o(datasets["converted"]).agents]
    split = np.bincount(contiguous_split(sum(sizes), len(sizes))).tolist()
    assert any("contiguous split" in w for w in res.warnings) == (split != sizes)
    # kollagen's 3D records carry 1e6 on z and the angle information on the rotation: anisotropic
    synth = export_dataset(datasets["synth"], tmp_path / "dp2", format="dpgo")
    assert any("anisotropic information" in w for w in synth.warnings)
    meta = json.loads((tmp_path / "dp" / "export.json").read_text())
    assert meta["warnings"] == list(res.warnings) and [a["symbol"] for a in meta["agents"]] == ["a", "b", "c"]


def test_tau_kappa_follow_dpgos_rule():
    # SE(3): tau = 3 / tr(I_tt^-1), kappa = 3 / (2 tr(I_rr^-1)) (DPGO_utils.cpp read_g2o_file)
    info = np.zeros((1, 6, 6))
    info[0, :3, :3] = np.diag([100.0, 200.0, 400.0])
    info[0, 3:, 3:] = np.diag([10.0, 20.0, 40.0])
    rows, cols = np.triu_indices(6)
    tau, kappa = tau_kappa(PoseKind.SE3, info[:, rows, cols])
    assert tau[0] == pytest.approx(3 / (1 / 100 + 1 / 200 + 1 / 400))
    assert kappa[0] == pytest.approx(3 / (2 * (1 / 10 + 1 / 20 + 1 / 40)))
    # SE(2): tau = 2 / tr(I_tt^-1), kappa = I33
    tau2, kappa2 = tau_kappa(PoseKind.SE2, np.array([[100.0, 0.0, 0.0, 300.0, 0.0, 7.0]]))
    assert tau2[0] == pytest.approx(2 / (1 / 100 + 1 / 300)) and kappa2[0] == 7.0


def test_export_refuses_an_existing_output_and_writes_nothing_on_bad_input(datasets, tmp_path):
    target = tmp_path / "x.jrl"
    assert runner.invoke(app, ["export", str(datasets["synth"]), "--format", "jrl", "-o", str(target)]).exit_code == 0
    r = runner.invoke(app, ["export", str(datasets["synth"]), "--format", "jrl", "-o", str(target)])
    assert r.exit_code == 2 and "already exists" in r.output
    r = runner.invoke(app, ["export", str(tmp_path / "nope"), "--format", "symbols", "-o", str(tmp_path / "s")])
    assert r.exit_code == 2 and len(r.output.strip().splitlines()) == 1 and not (tmp_path / "s").exists()


# ----------------------------------------------------------------------- single g2o and splits


def _relative(kind: PoseKind, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    if kind is PoseKind.SE2:
        c, s = np.cos(a[:, 2]), np.sin(a[:, 2])
        dx, dy = b[:, 0] - a[:, 0], b[:, 1] - a[:, 1]
        dth = np.arctan2(np.sin(b[:, 2] - a[:, 2]), np.cos(b[:, 2] - a[:, 2]))
        return np.stack([c * dx + s * dy, -s * dx + c * dy, dth], axis=1)
    qa_inv = quat_conj(a[:, 3:])
    return np.hstack([quat_rotate(qa_inv, b[:, :3] - a[:, :3]), quat_mul(qa_inv, b[:, 3:])])


def _grid_graph(kind: PoseKind, rows: int = 8, cols: int = 12) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A lawnmower walk over a rows x cols grid (the first pose at the origin), its odometry and a loop
    closure between every pair of poses that are neighbours across rows: a grid-like graph."""
    cells = [(r, c if r % 2 == 0 else cols - 1 - c) for r in range(rows) for c in range(cols)]
    xy = np.array([(c * 1.0, r * 1.0) for r, c in cells])
    heading = np.array([0.0 if r % 2 == 0 else np.pi for r, _ in cells])
    if kind is PoseKind.SE2:
        poses = np.column_stack([xy, heading])
    else:
        rng = np.random.default_rng(3)
        q = quat_mul(
            quat_from_rotvec(np.column_stack([np.zeros((len(xy), 2)), heading])),
            quat_from_rotvec(rng.normal(0, 0.05, (len(xy), 3))),
        )
        q[0] = [0, 0, 0, 1]
        poses = np.column_stack([xy, rng.normal(0, 0.1, len(xy)), q / np.linalg.norm(q, axis=1, keepdims=True)])
        poses[0, 2] = 0.0
    index = {cell: k for k, cell in enumerate(cells)}
    pairs = [(k, k + 1) for k in range(len(cells) - 1)]
    pairs += [
        (index[(r, c)], index[(r + 1, c)]) for r in range(rows - 1) for c in range(cols) if c not in (0, cols - 1)
    ]
    return poses, np.array(pairs), np.array(cells)


def _write_graph_file(path: Path, kind: PoseKind, *, vertices: bool = True, extra: str = "") -> np.ndarray:
    poses, pairs, _ = _grid_graph(kind)
    meas = _relative(kind, poses[pairs[:, 0]], poses[pairs[:, 1]])
    width = kind.information_width
    info = np.zeros((len(pairs), width))
    diag = np.cumsum([0, 3, 2]) if kind is PoseKind.SE2 else np.cumsum([0, 6, 5, 4, 3, 2])
    info[:, diag] = 100.0
    ids = np.arange(len(poses), dtype=np.int64) * 2 + 10  # ids need not start at 0 or be contiguous
    doc = G2oDocument(
        kind,
        ids if vertices else np.zeros(0, dtype=np.int64),
        poses if vertices else np.zeros((0, kind.pose_width)),
        ids[pairs[:, 0]],
        ids[pairs[:, 1]],
        meas,
        info,
    )
    write_g2o(path, doc)
    if extra:
        with open(path, "a", encoding="utf-8") as f:
            f.write(extra)
    return poses


def _cut(imported: PoseGraph) -> int:
    return len(imported.inter)


@pytest.mark.parametrize("kind", [PoseKind.SE2, PoseKind.SE3])
@pytest.mark.parametrize("vertices", [True, False])
@pytest.mark.parametrize("partition", ["contiguous", "metis", "time"])
def test_convert_g2o_splits_into_robots(tmp_path, kind, vertices, partition):
    f = tmp_path / "grid.g2o"
    poses = _write_graph_file(f, kind, vertices=vertices)
    n = len(poses)
    res = import_graph("g2o", [f], tmp_path / "ds", options=GraphImportOptions(split=3, partition=partition), rrd=False)
    g = read_multi_g2o(tmp_path / "ds")
    assert g.num_poses == n and len(g.agents) == 3
    assert sum(g.edge_counts().values()) == len(read_g2o(f, dangling=True).edge_from)
    assert len(res.graph.inter) > 0
    sizes = [a.num_poses for a in g.agents]
    if partition == "contiguous":
        assert sizes == [n // 3, n // 3, n - 2 * (n // 3)]
        # DPGO's rule on the file's own (renumbered) ids: an edge is inter-robot where the robots differ
        _, pairs, _ = _grid_graph(kind)
        robot = contiguous_split(n, 3)
        assert len(g.inter) == int(np.count_nonzero(robot[pairs[:, 0]] != robot[pairs[:, 1]]))
    if partition == "metis":
        assert max(sizes) - min(sizes) <= 0.1 * n
    if not vertices:
        # edges only: the initial estimate composed along the edges from the first pose (at the origin)
        initial = np.concatenate([a.initial for a in res.graph.agents])[:, :2]
        got = initial[np.lexsort(np.round(initial, 6).T[::-1])]
        want = poses[np.lexsort(np.round(poses[:, :2], 6).T[::-1]), :2]
        np.testing.assert_allclose(got, want, atol=1e-9)


def test_metis_cuts_no_more_edges_than_contiguous_on_a_grid(tmp_path):
    f = tmp_path / "grid.g2o"
    _write_graph_file(f, PoseKind.SE2)
    cuts = {}
    for partition in ("contiguous", "metis"):
        imp = import_graph(
            "g2o", [f], tmp_path / partition, options=GraphImportOptions(split=4, partition=partition), rrd=False
        )
        cuts[partition] = _cut(imp.graph)
    assert 0 < cuts["metis"] <= cuts["contiguous"]


def test_ground_truth_from_the_files_vertices(tmp_path):
    f = tmp_path / "grid.g2o"
    poses = _write_graph_file(f, PoseKind.SE2)
    imp = import_graph(
        "g2o",
        [f],
        tmp_path / "ds",
        options=GraphImportOptions(split=2, partition="time", ground_truth="vertices"),
        rrd=False,
    )
    truth = np.concatenate([a.ground_truth for a in imp.graph.agents])
    np.testing.assert_array_equal(truth, poses)
    # the initial estimate is the odometry's dead reckoning: exact measurements give the poses back
    np.testing.assert_allclose(np.concatenate([a.initial for a in imp.graph.agents]), poses, atol=1e-9)


def test_time_split_with_overlap_shares_the_overlapping_poses(tmp_path):
    f = tmp_path / "grid.g2o"
    poses = _write_graph_file(f, PoseKind.SE2)
    imp = import_graph(
        "g2o", [f], tmp_path / "ds", options=GraphImportOptions(split=2, partition="time", overlap_s=10.0), rrd=False
    )
    sizes = [a.num_poses for a in imp.graph.agents]
    assert sum(sizes) > len(poses)  # the overlap's poses are in both robots


def test_unknown_records_are_one_warning(tmp_path):
    f = tmp_path / "grid.g2o"
    _write_graph_file(f, PoseKind.SE2, extra="FIX 10\nEDGE_SE2_XY 10 12 1 0 1 0 1\nEDGE_SE2_XY 12 14 1 0 1 0 1\n")
    r = runner.invoke(app, ["convert", "g2o", str(f), "-o", str(tmp_path / "ds"), "--no-rrd", "-q"])
    assert r.exit_code == 0, r.output
    warnings = [line for line in r.output.splitlines() if line.startswith("warning:")]
    # FIX is read (the gauge), not skipped
    assert len(warnings) == 1 and "2 EDGE_SE2_XY" in warnings[0] and "FIX" not in warnings[0]


# ---------------------------------------------------------------------------------- bad inputs


def _fails_cleanly(args: list[str], out: Path, *needles: str) -> None:
    r = runner.invoke(app, args)
    assert r.exit_code == 2, r.output
    lines = r.output.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error:") and "Traceback" not in r.output, r.output
    for needle in needles:
        assert needle in lines[0], lines[0]
    assert not out.exists()
    assert not list(out.parent.glob(".studio-staging-*"))


def test_bad_jrl_files(datasets, tmp_path):
    export_dataset(datasets["synth"], tmp_path / "ok.jrl", format="jrl")
    doc = json.loads((tmp_path / "ok.jrl").read_text())
    no_robots = {k: v for k, v in doc.items() if k != "robots"}
    (tmp_path / "a.jrl").write_text(json.dumps(no_robots))
    _fails_cleanly(
        ["convert", "jrl", str(tmp_path / "a.jrl"), "-o", str(tmp_path / "o1")],
        tmp_path / "o1",
        "a.jrl",
        "missing key 'robots'",
    )
    unknown = dict(doc)
    unknown["measurements"] = {**doc["measurements"], "z": []}
    (tmp_path / "b.jrl").write_text(json.dumps(unknown))
    _fails_cleanly(
        ["convert", "jrl", str(tmp_path / "b.jrl"), "-o", str(tmp_path / "o2")],
        tmp_path / "o2",
        "b.jrl",
        "measurements.z",
        "'z' is not in robots",
    )
    missing_key = json.loads(json.dumps(doc))
    del missing_key["measurements"]["b"][2]["measurements"][0]["key2"]
    (tmp_path / "c.jrl").write_text(json.dumps(missing_key))
    _fails_cleanly(
        ["convert", "jrl", str(tmp_path / "c.jrl"), "-o", str(tmp_path / "o3")],
        tmp_path / "o3",
        "measurements.b[2].measurements[0]",
        "missing key 'key2'",
    )
    stranger = json.loads(json.dumps(doc))
    stranger["measurements"]["a"][0]["measurements"][0]["key2"] = symbol_key("q", 3).item()
    (tmp_path / "d.jrl").write_text(json.dumps(stranger))
    _fails_cleanly(
        ["convert", "jrl", str(tmp_path / "d.jrl"), "-o", str(tmp_path / "o4")],
        tmp_path / "o4",
        "measurements.a[0].measurements[0].key2",
        "names no robot",
    )


def test_jrl_stamps_beyond_int64_and_a_non_object_outlier_section(datasets, tmp_path):
    """Found by fuzzing the reader: both were tracebacks (OverflowError, AttributeError)."""
    export_dataset(datasets["synth"], tmp_path / "ok.jrl", format="jrl")
    doc = json.loads((tmp_path / "ok.jrl").read_text())
    big = json.loads(json.dumps(doc))
    big["measurements"]["a"][1]["stamp"] = 1 << 63
    (tmp_path / "e.jrl").write_text(json.dumps(big))
    _fails_cleanly(
        ["convert", "jrl", str(tmp_path / "e.jrl"), "-o", str(tmp_path / "o5")],
        tmp_path / "o5",
        "measurements.a[1].stamp",
        "beyond the studio's int64",
    )
    block = json.loads(json.dumps(doc))
    block["studio"]["stamps_ns"]["a"][0] = -(1 << 63) - 1
    (tmp_path / "f.jrl").write_text(json.dumps(block))
    _fails_cleanly(
        ["convert", "jrl", str(tmp_path / "f.jrl"), "-o", str(tmp_path / "o6")],
        tmp_path / "o6",
        "studio.stamps_ns.a",
        "64-bit signed",
    )
    labelled = dict(doc, outlier_factors=[1, 2])
    (tmp_path / "g.jrl").write_text(json.dumps(labelled))
    _fails_cleanly(
        ["convert", "jrl", str(tmp_path / "g.jrl"), "-o", str(tmp_path / "o7")],
        tmp_path / "o7",
        "outlier_factors",
        "expected an object",
    )


def test_colliding_symbol_keys(datasets, tmp_path):
    export_dataset(datasets["synth"], tmp_path / "sym", format="symbols")
    text = (tmp_path / "sym" / "1.g2o").read_text()
    b, a = str(symbol_key("b", 0))[:4], str(symbol_key("a", 0))[:4]
    (tmp_path / "sym" / "1.g2o").write_text(text.replace(f" {b}", f" {a}"))
    _fails_cleanly(
        ["convert", "symbols", str(tmp_path / "sym"), "-o", str(tmp_path / "o")], tmp_path / "o", "1.g2o", "collides"
    )


def test_measurements_csv_with_another_header(datasets, tmp_path):
    export_dataset(datasets["synth"], tmp_path / "dp", format="dpgo")
    csv = tmp_path / "dp" / "robot1" / "measurements.csv"
    lines = csv.read_text().splitlines()
    csv.write_text("\n".join(["robot_src,pose_src,robot_dst,pose_dst,x,y,z,qx,qy,qz,qw", *lines[1:]]) + "\n")
    _fails_cleanly(
        ["convert", "dpgo", str(tmp_path / "dp"), "-o", str(tmp_path / "o")],
        tmp_path / "o",
        "robot1/measurements.csv:1",
        "header",
    )


def test_split_larger_than_the_poses_and_a_disconnected_split(tmp_path):
    f = tmp_path / "grid.g2o"
    poses = _write_graph_file(f, PoseKind.SE2)
    _fails_cleanly(
        ["convert", "g2o", str(f), "--split", str(len(poses) + 1), "-o", str(tmp_path / "o1")],
        tmp_path / "o1",
        "grid.g2o",
        "more robots than",
    )
    # two separate chains: split in two, no edge joins the robots
    two = tmp_path / "two.g2o"
    k = PoseKind.SE2
    poses = np.column_stack([np.arange(10.0), np.zeros(10), np.zeros(10)])
    pairs = np.array([(i, i + 1) for i in range(9) if i != 4])
    doc = G2oDocument(
        k,
        np.arange(10),
        poses,
        pairs[:, 0],
        pairs[:, 1],
        _relative(k, poses[pairs[:, 0]], poses[pairs[:, 1]]),
        np.tile([100.0, 0, 0, 100.0, 0, 100.0], (len(pairs), 1)),
    )
    write_g2o(two, doc)
    _fails_cleanly(
        ["convert", "g2o", str(two), "--split", "2", "-o", str(tmp_path / "o2")],
        tmp_path / "o2",
        "two.g2o",
        "disconnected split",
    )
