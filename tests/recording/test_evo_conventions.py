"""The studio's Rerun conventions beside evo's own Rerun output (docs/recordings.md): evo's timelines
and entity roots, read from the installed evo, share no entity path with the studio's, and the one
timeline name both use, `time`, is a timestamp timeline in both."""

from __future__ import annotations

import inspect
import re

import pytest

from studio.recording import entities

evo_bridge = pytest.importorskip("evo.tools.rerun_bridge", reason="evo without Rerun support")


def _studio_paths() -> list[str]:
    return [v for k, v in vars(entities).items() if k.isupper() and isinstance(v, str) and "/" in v]


def test_evo_logs_to_rerun_on_time_and_index():
    assert evo_bridge.TIMELINE == "time" and evo_bridge.INDEX_TIMELINE == "index"
    source = inspect.getsource(evo_bridge)
    # evo's `time` is a timestamp timeline, as the studio's
    assert "rr.TimeColumn(TIMELINE, timestamp=" in source
    assert entities.TIMELINE_TIME == "time"
    dataset_source = inspect.getsource(__import__("studio.recording.dataset", fromlist=["x"]))
    assert "rr.TimeColumn(TIMELINE_TIME, timestamp=" in dataset_source
    assert entities.TIMELINE_NODE != evo_bridge.INDEX_TIMELINE


def test_no_entity_path_is_shared_with_evo():
    from evo.cli import common_ape_rpe, traj_rerun

    evo_roots = set(re.findall(r'"(evo_[a-z]+)/', inspect.getsource(traj_rerun)))
    evo_roots |= {"evo_ape", "evo_rpe"}  # common_ape_rpe's f"{evo_app_name}/..." with these app names
    assert "evo_app_name}/" in inspect.getsource(common_ape_rpe)
    assert evo_roots >= {"evo_traj"}
    studio_roots = {p.split("/")[0] for p in _studio_paths()} | {entities.WORLD, entities.METRICS}
    assert studio_roots and not studio_roots & evo_roots
    assert not entities.APPLICATION_ID.startswith("evo_")
