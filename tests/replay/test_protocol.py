"""The back-end protocol (studio.replay.protocol): what a back-end is told over a replay. A back-end
registered for the test records every Checkpoint: each pose and own edge is told once, at the first
checkpoint at or after its time; each delivered closure once, at the checkpoint of its delivery; the
groups are the replay's; the end comes once, after the last checkpoint."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from studio.core.comms import robot_pairs
from studio.replay import replay
from studio.replay.protocol import Checkpoint, Setup, Step
from studio.replay.registry import BACKENDS
from studio.synth import load_synth_config, synthesize

DATA = Path(__file__).resolve().parent.parent / "data"


class Recorder:
    made: list[Recorder] = []

    def __init__(self, setup: Setup) -> None:
        self.setup, self.news, self.ends = setup, [], 0
        Recorder.made.append(self)

    def _step(self) -> Step:
        zeros = np.zeros(len(robot_pairs(self.setup.num_robots)), dtype=np.int64)
        return Step(self.setup.problem.initial.copy(), 0.0, zeros, zeros)

    def advance(self, news: Checkpoint) -> Step:
        assert self.ends == 0
        self.news.append(news)
        return self._step()

    def finish(self) -> Step:
        self.ends += 1
        return self._step()


@pytest.fixture(scope="module")
def tiny(tmp_path_factory):
    root = tmp_path_factory.mktemp("protocol")
    return synthesize(load_synth_config(DATA / "configs" / "tiny_three.json"), root, rrd=False, jobs=1).dataset_dir


def test_each_fact_is_told_once_at_its_time(tiny, tmp_path, monkeypatch):
    monkeypatch.setitem(BACKENDS, "recorder", Recorder)
    Recorder.made.clear()
    res = replay(tiny, tmp_path / "r", backends=["recorder"], comms="range:15,p=0.7", every=10, seed=3)
    (rec,) = Recorder.made
    s = res.schedule
    assert rec.ends == 1 and [n.tick for n in rec.news] == res.runs[0].checkpoint_ticks.tolist()
    p, agent = rec.setup.problem, rec.setup.agent_of_vertex
    inter = rec.setup.inter_edges()
    vertices = np.concatenate([n.vertices for n in rec.news])
    edges = np.concatenate([n.edges for n in rec.news])
    closures = np.concatenate([n.closures for n in rec.news])
    assert len(np.unique(vertices)) == len(vertices) == p.num_vertices  # every pose, once
    assert len(np.unique(edges)) == len(edges) == int((~inter).sum())  # every own edge, once
    assert not inter[edges].any() and inter[closures].all()
    assert len(closures) == int((s.delivered_tick >= 0).sum()) > 0  # every delivered closure, once
    previous = -1
    for n in rec.news:
        t, before = s.ticks_ns[n.tick], s.ticks_ns[previous] if previous >= 0 else -np.inf
        assert ((n.vertex_ns > before) & (n.vertex_ns <= t)).all() and n.time_ns == t
        assert ((n.edge_ns > before) & (n.edge_ns <= t)).all()
        # a closure's index among the inter-agent edges is its row of the schedule
        rows = np.searchsorted(np.flatnonzero(inter), n.closures)
        assert ((s.delivered_tick[rows] > previous) & (s.delivered_tick[rows] <= n.tick)).all()
        assert all(len(g) >= 1 for g in n.groups) and n.contacts.shape[1:] == (2,)
        group_of = {r: k for k, g in enumerate(n.groups) for r in g}
        for a, b in n.contacts.tolist():  # robots in contact share a group when both are present
            assert a not in group_of or b not in group_of or group_of[a] == group_of[b]
        previous = n.tick
    assert (agent[p.edge_from[closures]] != agent[p.edge_to[closures]]).all()
