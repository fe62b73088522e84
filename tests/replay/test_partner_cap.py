"""iMESA's communication model (a cap on partners per round, rounds per tick, p after the cap) on
hand-made contact patterns whose pairs are known (rpl-cmu/imesa-experiments'
``CommunicationModel::getStepCommunication``)."""

from __future__ import annotations

import numpy as np
import pytest

from studio.core.comms import (
    Bandwidth,
    PartnerCap,
    RangeLimited,
    Rendezvous,
    contacts,
    deliver,
    parse_comms,
    robot_pairs,
    tick_grid,
)
from studio.core.errors import ConfigError
from studio.core.units import NS_PER_S

TICKS = 50


def _still(xs: list[float], ticks: int = TICKS) -> dict:
    """Robots standing at ``x`` (m) on a line, present from 0 s to the last tick."""
    end = (ticks - 1) * NS_PER_S
    pose_ns = tuple(np.array([0, end]) for _ in xs)
    xyz = tuple(np.array([[x, 0.0, 0.0], [x, 0.0, 0.0]]) for x in xs)
    return {"ticks_ns": tick_grid(0, end, NS_PER_S), "pose_ns": pose_ns, "positions_xyz": xyz}


def _pairs_at(c: np.ndarray, n: int, t: int) -> list[tuple[int, int]]:
    return [tuple(p) for p in robot_pairs(n)[c[t]].tolist()]


def _degree(c: np.ndarray, n: int) -> np.ndarray:
    pairs = robot_pairs(n)
    return np.stack([c[:, (pairs[:, 0] == k) | (pairs[:, 1] == k)].sum(axis=1) for k in range(n)], axis=1)


def test_the_specs_parse_round_trip_and_bad_values_name_the_option():
    m = parse_comms("range:30,partners=1,p=0.9")  # iMESA's experiments/config/communication_models/pairwise.json
    assert m == PartnerCap(RangeLimited(30.0), 1, 1, 0.9) and m.spec() == "range:30,partners=1,p=0.9"
    m = parse_comms("range:5,period=2,partners=2,rounds=3")
    assert m == PartnerCap(RangeLimited(5.0, 2 * NS_PER_S), 2, 3, 1.0)
    assert m.spec() == "range:5,period=2,partners=2,rounds=3"
    assert parse_comms("range:5,p=0.5") == RangeLimited(5.0, None, 0.5)  # range's own draw, unchanged
    assert parse_comms("rendezvous:a,b.txt,rounds=2,partners=1") == PartnerCap("a,b.txt", 1, 2, 1.0)
    assert parse_comms("rendezvous:a,b.txt") == "a,b.txt"
    for bad, match in [
        ("range:5,partners=0", "partners .* must be > 0"),
        ("range:5,partners=1.5", "partners .* whole number"),
        ("range:5,rounds=0", "rounds .* must be > 0"),
        ("range:5,partners=1,partners=2", "'partners' given twice"),
        ("range:5,partners=1,p=2", r"\[0, 1\]"),
        ("range:5,cap=1", "unknown option 'cap'.*partners, rounds, p"),
        ("rendezvous:,partners=1", "needs a file"),
        ("rendezvous:f.txt,rounds=x", "rounds .* not a number"),
    ]:
        with pytest.raises(ConfigError, match=match):
            parse_comms(bad)


def test_two_far_clusters_each_keep_their_pair_whatever_the_order():
    # 0 and 1 together, 2 and 3 together 100 m away: under a cap of 1 both pairs are taken at every tick
    world = _still([0.0, 1.0, 100.0, 101.0])
    for seed in range(5):
        c = contacts(PartnerCap(RangeLimited(5.0), 1), seed=seed, **world)
        assert all(_pairs_at(c, 4, t) == [(0, 1), (2, 3)] for t in range(TICKS))


def test_a_chain_gives_the_middle_robot_to_whichever_end_comes_first_in_the_order():
    # 0 -- 1 -- 2, 4 m apart, range 5: 0 and 2 cannot talk; with one partner each, robot 1 talks to
    # the end robot that comes first in the tick's random order (one permutation, then one draw per
    # pair taken, from the generator seeded by the seed)
    world = _still([0.0, 4.0, 8.0])
    c = contacts(PartnerCap(RangeLimited(5.0), 1), seed=3, **world)
    rng = np.random.default_rng(3)
    expected = []
    for _ in range(TICKS):
        order = rng.permutation(3).tolist()
        rng.random(1)
        expected.append([(0, 1)] if order.index(0) < order.index(2) else [(1, 2)])
    got = [_pairs_at(c, 3, t) for t in range(TICKS)]
    assert got == expected
    assert [(0, 1)] in got and [(1, 2)] in got  # both ends get their turn
    # without the cap, both links every tick
    free = contacts(RangeLimited(5.0), seed=3, **world)
    assert free[:, [0, 2]].all() and not free[:, 1].any()


def test_four_together_under_one_partner_pair_off_as_the_order_says():
    world = _still([0.0, 1.0, 2.0, 3.0])
    c = contacts(PartnerCap(RangeLimited(10.0), 1), seed=11, **world)
    rng = np.random.default_rng(11)
    for t in range(TICKS):
        a, b, x, y = rng.permutation(4).tolist()
        rng.random(2)
        assert _pairs_at(c, 4, t) == sorted([tuple(sorted((a, b))), tuple(sorted((x, y)))])
    assert (_degree(c, 4) == 1).all()
    # two partners each, in the order a b x y: the visits (a,b) (a,x) (a,y) (b,x) (b,y) (x,y) take
    # (a,b) (a,x), a is full, then (b,x): the first three talk to each other, the last to nobody
    two = contacts(PartnerCap(RangeLimited(10.0), 2), seed=11, **world)
    rng = np.random.default_rng(11)
    for t in range(TICKS):
        first = sorted(rng.permutation(4).tolist()[:3])
        rng.random(3)
        assert _pairs_at(two, 4, t) == [(first[0], first[1]), (first[0], first[2]), (first[1], first[2])]
    # the cap above the team's size changes nothing
    three = contacts(PartnerCap(RangeLimited(10.0), 3), seed=11, **world)
    assert three.all()


def test_rounds_draw_afresh_and_a_robot_talks_to_at_most_partners_times_rounds():
    world = _still([0.0, 1.0, 2.0, 3.0, 4.0])
    one = contacts(PartnerCap(RangeLimited(10.0), 1, 1), seed=5, **world)
    two = contacts(PartnerCap(RangeLimited(10.0), 1, 2), seed=5, **world)
    assert (_degree(one, 5) <= 1).all() and (one.sum(axis=1) == 2).all()  # 5 robots: 2 pairs, one left out
    assert (_degree(two, 5) <= 2).all() and (_degree(two, 5) == 2).any()
    assert (two.sum(axis=1) >= 2).all() and two.sum() > one.sum()
    again = contacts(PartnerCap(RangeLimited(10.0), 1, 2), seed=5, **world)
    other = contacts(PartnerCap(RangeLimited(10.0), 1, 2), seed=6, **world)
    assert np.array_equal(two, again) and not np.array_equal(two, other)


def test_a_contact_lost_after_the_cap_still_used_its_place():
    # three together, one partner, p = 0.5: a tick has one pair (kept) or none (lost); never a
    # second pair in place of a lost one (which would give a contact at 1 - 0.5^3 of the ticks)
    world = _still([0.0, 1.0, 2.0], ticks=2000)
    c = contacts(PartnerCap(RangeLimited(10.0), 1, 1, 0.5), seed=2, **world)
    per_tick = c.sum(axis=1)
    assert per_tick.max() == 1
    assert 0.45 < per_tick.mean() < 0.55
    assert not contacts(PartnerCap(RangeLimited(10.0), 1, 1, 0.0), **world).any()


def test_the_cap_composes_with_period_rendezvous_and_bandwidth():
    world = _still([0.0, 4.0, 8.0])
    every3 = contacts(PartnerCap(RangeLimited(5.0, 3 * NS_PER_S), 1), seed=1, **world)
    assert np.flatnonzero(every3.any(axis=1)).tolist() == list(range(0, TICKS, 3))
    assert (every3.sum(axis=1) <= 1).all()
    # rendezvous: 0 and 1 meet in 0..9 s, all three in 20..29 s (the cap then picks one pair)
    windows = (np.array([[0, 9], [20, 29]]), np.array([[0, 29]]), np.array([[20, 29]]))
    c = contacts(PartnerCap(Rendezvous(windows, "f"), 1), seed=4, **world)
    assert all(_pairs_at(c, 3, t) == [(0, 1)] for t in range(10))
    assert not c[10:20].any() and not c[30:].any()
    assert (c[20:30].sum(axis=1) == 1).all() and len({tuple(r) for r in c[20:30].tolist()}) > 1
    # deliveries follow the capped contacts: a 1/s link carries one closure per tick of contact
    pair = np.array([0, 0, 0])
    got = deliver(c, ticks_ns=world["ticks_ns"], closure_pair=pair, measured_ns=np.zeros(3, np.int64),
                  bandwidth=Bandwidth(1.0))  # fmt: skip
    assert got.tolist() == [0, 1, 2]
    with pytest.raises(ConfigError, match="read first"):
        contacts(PartnerCap("f.txt", 1), **world)


def test_a_replay_under_the_cap_records_it_and_copies_the_rendezvous_file(tmp_path):
    pytest.importorskip("gtsam")
    from pathlib import Path

    from studio.replay import replay
    from studio.synth import load_synth_config, synthesize

    data = Path(__file__).resolve().parent.parent / "data" / "configs" / "tiny_three.json"
    made = synthesize(load_synth_config(data), tmp_path / "d", rrd=False, jobs=1)
    sched = tmp_path / "rdv.txt"
    sched.write_text("0,0,240\n1,0,240\n2,0,240\n")
    spec = f"rendezvous:{sched},partners=1,rounds=2"
    res = replay(made.dataset_dir, tmp_path / "r", comms=spec, backends=["swarm"], every=20, seed=3)
    assert (
        res.options["comms"] == spec and (res.out_dir / "schedule" / "rendezvous.txt").read_text() == sched.read_text()
    )
    assert (_degree(res.schedule.contact, 3) <= 2).all() and not res.schedule.contact.all()
    again = replay(made.dataset_dir, tmp_path / "r2", comms=spec, backends=["swarm"], every=20, seed=3)
    assert (again.out_dir / "metrics.csv").read_bytes() == (res.out_dir / "metrics.csv").read_bytes()
    free = replay(made.dataset_dir, tmp_path / "r3", comms=f"rendezvous:{sched}", backends=["swarm"], every=20)
    assert free.schedule.contact.sum() > res.schedule.contact.sum()
