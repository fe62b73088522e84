"""The in-memory generator (issue 28): studio.synth.generate / generate_many return the graphs that
`studio synth` writes, replicates draw the seeds `studio sweep` draws, nothing touches the disk."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from studio.core.errors import ConfigError
from studio.core.model import graphs_equal
from studio.generator.config import replicate_config, replicate_seed
from studio.io.multig2o import read_multi_g2o, write_multi_g2o
from studio.io.synth_config import read_synth_config
from studio.synth import generate, generate_many, load_synth_config, synthesize

DATA = Path(__file__).resolve().parents[1] / "data" / "configs"


@pytest.fixture(scope="module")
def config():
    return load_synth_config(DATA / "small3x100.json")


def test_generate_is_the_graph_synth_writes_byte_for_byte(config, tmp_path):
    graph = generate(config)
    assert len(graph.agents) == 3 and graph.num_poses == 3 * config.poses_per_agent
    synthesized = synthesize(config, tmp_path / "synth", rrd=False).dataset_dir
    (tmp_path / "mine").mkdir()
    write_multi_g2o(graph, tmp_path / "mine")
    files = sorted(p.relative_to(synthesized) for p in synthesized.rglob("*") if p.is_file())
    assert len(files) >= 7  # three agents' graph and ground truth, the inter-agent closures
    for rel in files:
        assert (tmp_path / "mine" / rel).read_bytes() == (synthesized / rel).read_bytes(), rel
    assert graphs_equal(read_multi_g2o(tmp_path / "mine"), read_multi_g2o(synthesized))


def test_replicates_draw_the_seeds_of_the_sweep(config, tmp_path):
    from studio.sweep import _apply

    base = json.loads((DATA / "small3x100.json").read_text())
    swept = tmp_path / "small3x100.json"
    swept.write_text(json.dumps(_apply("synth", base, {"seed": 7}, "cell")))
    assert replicate_config(config, 7) == read_synth_config(swept)
    assert replicate_seed(42, 0) == 42 and replicate_seed(2**31 - 2, 1) == (2**31 - 2 + 1_000_003) % (2**31 - 1)
    with pytest.raises(ConfigError, match="seed: expected a non-negative integer"):
        replicate_config(config, -1)


def test_generate_many_in_order_whatever_the_processes(config):
    one = list(generate_many(config, [0, 5, 9], jobs=1))
    two = list(generate_many(config, [0, 5, 9], jobs=2))
    assert all(graphs_equal(a, b) for a, b in zip(one, two)) and len(two) == 3
    assert graphs_equal(one[0], generate(config))
    first = [a.initial for a in one[0].agents]
    other = [a.initial for a in one[1].agents]
    assert not all(np.array_equal(a, b) for a, b in zip(first, other))  # another replicate, another walk
