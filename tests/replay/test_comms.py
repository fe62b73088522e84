"""Measurement times and communication models: pure functions on small hand-made inputs."""

from __future__ import annotations

import io

import numpy as np
import pytest

from studio.core.comms import (
    Always,
    Bandwidth,
    Never,
    RangeLimited,
    Recorded,
    Rendezvous,
    Schedule,
    comms_report,
    contacts,
    deliver,
    parse_bandwidth,
    parse_comms,
    robot_pairs,
    tick_grid,
)
from studio.core.comms_registry import COMMS_MODELS, comms_grammar
from studio.core.errors import ConfigError, FormatError, GraphError
from studio.core.model import AgentGraph, Edges, InterAgentEdges, PoseGraph, PoseKind
from studio.core.timing import measurement_times
from studio.core.units import NS_PER_S
from studio.io.rendezvous_txt import read_rendezvous, rendezvous_text
from studio.io.schedule_csv import closures_text, contacts_text


def _agent(name: str, n: int, stamps_s: list[float] | None = None) -> AgentGraph:
    poses = np.column_stack([np.arange(n, dtype=float), np.zeros(n), np.zeros(n)])
    stamps = np.arange(n) * NS_PER_S if stamps_s is None else (np.asarray(stamps_s) * NS_PER_S).astype(np.int64)
    info = np.tile([100.0, 0, 0, 100.0, 0, 100.0], (n - 1, 1))
    odo = Edges(PoseKind.SE2, np.arange(n - 1), np.arange(1, n), np.tile([1.0, 0, 0], (n - 1, 1)), info)
    lc = Edges(PoseKind.SE2, [n - 1], [0], [[-(n - 1.0), 0, 0]], [[100.0, 0, 0, 100.0, 0, 100.0]])
    return AgentGraph(name, PoseKind.SE2, stamps, poses, poses, odo, lc)


def _graph() -> PoseGraph:
    a, b = _agent("a", 5), _agent("b", 4, [0.5, 1.5, 2.5, 10.0])
    inter = InterAgentEdges(
        PoseKind.SE2, [0, 1], [4, 0], [1, 0], [1, 0], [[0.0, 0, 0], [0.0, 0, 0]], [[1.0, 0, 0, 1, 0, 1]] * 2
    )
    return PoseGraph(PoseKind.SE2, (a, b), inter)


def test_every_measurement_is_made_at_its_later_pose_and_closures_when_both_robots_were_there():
    times = measurement_times(_graph())
    assert times.odometry_ns[0].tolist() == [1 * NS_PER_S, 2 * NS_PER_S, 3 * NS_PER_S, 4 * NS_PER_S]
    assert times.odometry_ns[1].tolist() == [1_500_000_000, 2_500_000_000, 10 * NS_PER_S]
    assert times.loop_closure_ns[0].tolist() == [4 * NS_PER_S]  # edge 4 -> 0: the later pose is 4
    assert times.loop_closure_ns[1].tolist() == [10 * NS_PER_S]
    # a4 (4 s) with b1 (1.5 s): 4 s; b0 (0.5 s) with a0 (0 s): 0.5 s
    assert times.inter_ns.tolist() == [4 * NS_PER_S, 500_000_000]
    assert times.period_ns is None and times.start_ns == 0 and times.end_ns == 10 * NS_PER_S


def test_a_period_replaces_the_stamps_by_the_pose_index_and_is_recorded():
    times = measurement_times(_graph(), period_ns=2 * NS_PER_S)
    assert times.pose_ns[1].tolist() == [0, 2 * NS_PER_S, 4 * NS_PER_S, 6 * NS_PER_S]
    assert times.inter_ns.tolist() == [8 * NS_PER_S, 0]
    assert times.period_ns == 2 * NS_PER_S
    with pytest.raises(ConfigError, match="period"):
        measurement_times(_graph(), period_ns=-1)


def test_stamps_running_backwards_are_refused_by_the_model():
    with pytest.raises(GraphError, match="stamps must increase"):
        _agent("c", 3, [0.0, 2.0, 1.0])


def test_the_comms_specs_parse_and_bad_ones_name_the_problem():
    assert parse_comms("always") == Always() and parse_comms("never") == Never()
    m = parse_comms("range:5,period=2.5,p=0.3")
    assert m == RangeLimited(5.0, 2_500_000_000, 0.3) and m.spec() == "range:5,period=2.5,p=0.3"
    assert parse_comms("rendezvous:x/y.txt") == "x/y.txt"
    for bad, match in [
        ("range:-5", "must be > 0"),
        ("range:5,period=-1", "must be > 0"),
        ("range:5,p=1.5", r"\[0, 1\]"),
        ("range:5,q=1", "unknown option 'q'"),
        ("radio", "unknown model"),
        ("rendezvous:", "needs a file"),
        ("range", "range needs a distance"),
        ("always:3", "always takes no argument"),
        ("recorded:x", "recorded takes no argument"),
    ]:
        with pytest.raises(ConfigError, match=match):
            parse_comms(bad)
    assert parse_bandwidth("3/s") == Bandwidth(3.0, "measurements")
    assert parse_bandwidth("1000B/s") == Bandwidth(1000.0, "bytes")
    with pytest.raises(ConfigError, match="bandwidth"):
        parse_bandwidth("-3/s")


def test_every_registered_model_parses_by_its_entry_and_an_unknown_one_lists_them_all():
    """The registry is the one list: each entry's grammar (with its placeholders filled in) parses
    to a model whose spec names the entry, and the error for an unknown model lists every grammar."""
    examples = {"always": "always", "never": "never", "range": "range:3", "recorded": "recorded"}
    assert set(examples) | {"rendezvous"} == set(COMMS_MODELS)  # a new model gets an example here
    for spec in examples.values():
        assert parse_comms(spec).spec() == spec
    assert parse_comms("rendezvous:f.txt") == "f.txt"  # the file, read by the replay
    assert parse_comms(" recorded ") == Recorded()
    with pytest.raises(ConfigError) as err:
        parse_comms("radio")
    assert str(err.value) == f"comms: unknown model 'radio' (known: {comms_grammar()})"
    for entry in COMMS_MODELS.values():
        assert entry.grammar in str(err.value)


def test_recorded_contacts_are_the_closures_own_ticks_and_deliver_each_then():
    # robots 0,1,2: closures 0-1 at 2 s and 6.5 s, 1-2 at 3 s, one within robot 2 (pair -1) at 4 s,
    # and 0-1 after the last tick (never delivered, as under always)
    ticks = tick_grid(0, 10 * NS_PER_S, NS_PER_S)
    pose_ns = tuple(np.array([0, 10 * NS_PER_S]) for _ in range(3))
    pair = np.array([0, 2, -1, 0, 0])
    measured = np.array([2 * NS_PER_S, 3 * NS_PER_S, 4 * NS_PER_S, 6_500_000_000, 11 * NS_PER_S])
    c = contacts(
        Recorded(), ticks_ns=ticks, pose_ns=pose_ns, positions_xyz=None, closure_pair=pair, measured_ns=measured
    )
    assert [np.flatnonzero(c[:, p]).tolist() for p in range(3)] == [[2, 7], [], [3]]
    got = deliver(c, ticks_ns=ticks, closure_pair=pair, measured_ns=measured)
    assert got.tolist() == [2, 3, 4, 7, -1]
    # the same ticks as always-on links: only the contacts differ
    on = contacts(Always(), ticks_ns=ticks, pose_ns=pose_ns, positions_xyz=None)
    assert np.array_equal(got, deliver(on, ticks_ns=ticks, closure_pair=pair, measured_ns=measured))
    with pytest.raises(ConfigError, match="recorded needs the dataset's inter-agent closures"):
        contacts(Recorded(), ticks_ns=ticks, pose_ns=pose_ns, positions_xyz=None)


def test_range_contacts_follow_the_ground_truth_distance_period_and_seeded_draws():
    # robot 0 still at x=0, robot 1 walks away 1 m/s along x: within 2.5 m for t <= 2.5 s
    pose_ns = (np.array([0, 10 * NS_PER_S]), np.array([0, 10 * NS_PER_S]))
    xyz = (np.zeros((2, 3)), np.array([[0.0, 0, 0], [10.0, 0, 0]]))
    ticks = tick_grid(0, 10 * NS_PER_S, NS_PER_S)
    near = contacts(RangeLimited(2.5), ticks_ns=ticks, pose_ns=pose_ns, positions_xyz=xyz)
    assert near[:, 0].tolist() == [True, True, True] + [False] * 8
    every2 = contacts(RangeLimited(20.0, 2 * NS_PER_S), ticks_ns=ticks, pose_ns=pose_ns, positions_xyz=xyz)
    assert np.flatnonzero(every2[:, 0]).tolist() == [0, 2, 4, 6, 8, 10]
    a = contacts(RangeLimited(20.0, None, 0.5), ticks_ns=ticks, pose_ns=pose_ns, positions_xyz=xyz, seed=7)
    b = contacts(RangeLimited(20.0, None, 0.5), ticks_ns=ticks, pose_ns=pose_ns, positions_xyz=xyz, seed=7)
    c = contacts(RangeLimited(20.0, None, 0.5), ticks_ns=ticks, pose_ns=pose_ns, positions_xyz=xyz, seed=8)
    assert np.array_equal(a, b) and not np.array_equal(a, c) and 0 < a.sum() < 11
    with pytest.raises(ConfigError, match="ground truth"):
        contacts(RangeLimited(1.0), ticks_ns=ticks, pose_ns=pose_ns, positions_xyz=None)


def test_rendezvous_windows_need_both_robots_alive():
    pose_ns = tuple(np.array([0, 20 * NS_PER_S]) for _ in range(3))
    windows = (np.array([[0, 4], [10, 12]]), np.array([[3, 11]]), np.zeros((0, 2), dtype=np.int64))
    ticks = tick_grid(0, 20 * NS_PER_S, NS_PER_S)
    c = contacts(Rendezvous(windows, "f"), ticks_ns=ticks, pose_ns=pose_ns, positions_xyz=None)
    assert robot_pairs(3).tolist() == [[0, 1], [0, 2], [1, 2]]
    assert np.flatnonzero(c[:, 0]).tolist() == [3, 4, 10, 11]
    assert not c[:, 1].any() and not c[:, 2].any()  # robot 2 has no line: never alive


def test_delivery_waits_for_contact_and_the_bandwidth_queues_the_rest():
    ticks = tick_grid(0, 9 * NS_PER_S, NS_PER_S)
    contact = np.zeros((10, 1), dtype=bool)
    contact[[2, 3, 7], 0] = True
    measured = np.array([0, 0, 0, 5, 9]) * NS_PER_S
    pair = np.zeros(5, dtype=np.int64)
    free = deliver(contact, ticks_ns=ticks, closure_pair=pair, measured_ns=measured)
    assert free.tolist() == [2, 2, 2, 7, -1]
    one = deliver(contact, ticks_ns=ticks, closure_pair=pair, measured_ns=measured, bandwidth=Bandwidth(1.0))
    assert one.tolist() == [2, 3, 7, -1, -1]  # one per tick of contact, oldest first
    # 100 bytes per second with 50-byte closures: two per tick
    two = deliver(
        contact, ticks_ns=ticks, closure_pair=pair, measured_ns=measured, bandwidth=Bandwidth(100.0, "bytes"),
        closure_bytes=50,
    )  # fmt: skip
    assert two.tolist() == [2, 2, 3, 7, -1]


def test_the_report_counts_contacts_disconnections_and_deliveries():
    ticks = tick_grid(0, 5 * NS_PER_S, NS_PER_S)
    contact = np.array([[1, 0, 0], [1, 0, 0], [0, 0, 0], [1, 0, 1], [0, 0, 0], [0, 0, 0]], dtype=bool)
    s = Schedule(
        "test", ("a", "b", "c"), ticks, contact, np.array([0, 0]), np.array([1, 1]),
        np.array([0, 4]) * NS_PER_S, np.array([0, -1]),
    )  # fmt: skip
    r = comms_report(s)
    assert s.windows().tolist() == [[0, 1, 0, 1], [0, 1, 3, 3], [1, 2, 3, 3]]
    assert r.contacts_per_pair.tolist() == [2, 0, 1]
    assert r.disconnections.tolist() == [2, 2, 1]
    assert r.connected_fraction.tolist() == pytest.approx([0.5, 0.5, 1 / 6])
    assert r.robots_in_contact.tolist() == [2, 2, 0, 3, 0, 0]
    assert r.detected.tolist() == [1, 1, 1, 1, 2, 2] and r.delivered.tolist() == [1] * 6
    assert contacts_text(s).splitlines() == [
        "robot_a,robot_b,start_ns,end_ns",
        "a,b,0,1000000000",
        "a,b,3000000000,3000000000",
        "b,c,3000000000,3000000000",
    ]
    assert closures_text(s, np.array([3, 4]), np.array([5, 6])).splitlines()[1:] == [
        "0,a,3,b,5,0,0,0",
        "1,a,4,b,6,4000000000,-1,-1",
    ]


def test_lines_for_robots_the_dataset_lacks_are_one_warning():
    """cslam_experiments' schedules name up to six robots; each Swarm-SLAM robot reads its own line."""
    text = "0,0,4\n1,3,11\n2,0,9\n3,5,7\n4,1,2\n5,0,30\n"
    warnings: list[str] = []
    windows = read_rendezvous(io.StringIO(text), 3, warn=warnings.append)
    assert [w.tolist() for w in windows] == [[[0, 4]], [[3, 11]], [[0, 9]]]
    assert len(warnings) == 1 and "robots 3, 4, 5" in warnings[0] and "robots 0..2" in warnings[0]
    assert read_rendezvous(io.StringIO(text), 6, warn=warnings.append)[5].tolist() == [[0, 30]]
    assert len(warnings) == 1


def test_the_rendezvous_file_round_trips_and_bad_lines_name_file_and_line():
    text = "0,0,4,10,12\n\n1,3,11\n"
    windows = read_rendezvous(io.StringIO(text), 3)
    assert [w.tolist() for w in windows] == [[[0, 4], [10, 12]], [[3, 11]], []]
    assert rendezvous_text(windows) == "0,0,4,10,12\n1,3,11\n"
    for bad, match in [
        ("-1,0,4\n", "<stream>:1: robot id -1 is negative"),
        ("0,0,4\n0,5,6\n", "<stream>:2: robot 0 already has a line"),
        ("5,0,4\n5,6,8\n", "<stream>:2: robot 5 already has a line"),
        ("5,4,0\n", "<stream>:1: window 1 ends"),
        ("0,10,12,0,4\n", "<stream>:1: window 2 .* out of order or overlaps"),
        ("0,0,4,3,6\n", "<stream>:1: window 2 .* overlaps"),
        ("0,6,4\n", "<stream>:1: window 1 ends"),
        ("0,-1,4\n", "<stream>:1: window 1 has a negative time"),
        ("0,1\n", "odd number"),
        ("0,a,b\n", "<stream>:1: expected ROBOT_ID"),
    ]:
        with pytest.raises(FormatError, match=match):
            read_rendezvous(io.StringIO(bad), 3)
