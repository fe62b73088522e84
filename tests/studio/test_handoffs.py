"""Hand-offs between commands, through the CLI: `studio evaluate` takes what `studio solve` wrote (its
folder, its solve.json, the estimate inside) and kollagen's single-g2o dataset (NAME.g2o + NAME_GT.tum)."""

from __future__ import annotations

import dataclasses
import json
import shutil

import pytest
from typer.testing import CliRunner

from studio.cli import app
from studio.generator.presets import preset
from studio.synth import synthesize

pytest.importorskip("gtsam")

runner = CliRunner()


@pytest.fixture(scope="module")
def small(tmp_path_factory):
    base = preset("multi3500x8")
    cfg = dataclasses.replace(base, number_of_steps=40, number_of_agents=3, agents=base.agents[:3], name="Small")
    return synthesize(cfg, tmp_path_factory.mktemp("synth"), rrd=False)


@pytest.fixture(scope="module")
def solved(small, tmp_path_factory):
    """`studio solve` of the multi-g2o folder and of the single g2o, each into its own folder."""
    base = tmp_path_factory.mktemp("solved")
    multi, single = base / "multi", base / "single"
    for dataset, out in ((small.dataset_dir, multi), (small.single_dir / "Small.g2o", single)):
        res = runner.invoke(app, ["solve", str(dataset), "-o", str(out)])
        assert res.exit_code == 0, res.output
    return multi, single


def _scores(*args: str) -> dict:
    res = runner.invoke(app, ["evaluate", *map(str, args), "--json"])
    assert res.exit_code == 0, res.output
    data = json.loads(res.stdout)
    del data["estimate"]
    return data


def test_evaluate_takes_the_folder_solve_wrote(small, solved):
    multi, single = solved
    assert (multi / "estimate").is_dir() and (multi / "solve.json").is_file()
    direct = _scores(small.dataset_dir, "--estimate", multi / "estimate")
    assert direct["estimate_layout"] == "multi-g2o"
    assert _scores(small.dataset_dir, "--estimate", multi) == direct
    assert _scores(small.dataset_dir, "--estimate", multi / "solve.json") == direct
    # the optimum is far better than dead reckoning
    initial = _scores(small.dataset_dir)
    assert direct["all"]["ape_translation_m"]["mean"] < 0.5 * initial["all"]["ape_translation_m"]["mean"]
    # a single g2o solve: its folder stands for its <stem>.g2o
    from_file = _scores(small.dataset_dir, "--estimate", single / "Small.g2o")
    assert from_file["estimate_layout"] == "single-g2o"
    assert _scores(small.dataset_dir, "--estimate", single) == from_file


def test_an_estimate_folder_without_solve_json_is_taken_by_its_estimate_inside(small, solved, tmp_path):
    copy = tmp_path / "copy"
    shutil.copytree(solved[0] / "estimate", copy / "estimate")
    assert _scores(small.dataset_dir, "--estimate", copy) == _scores(small.dataset_dir, "--estimate", solved[0])


def test_evaluate_takes_a_single_g2o_dataset(small, solved):
    single = small.single_dir / "Small.g2o"
    one = _scores(single)
    assert [a["name"] for a in one["agents"]] == ["Small"]  # one agent: the file does not say where agents end
    multi = _scores(small.dataset_dir)
    # kollagen's paper figure: APE over all poses pooled, the same from either view
    assert one["all"]["ape_translation_m"]["mean"] == pytest.approx(
        multi["all"]["ape_translation_m"]["mean"], rel=1e-12
    )
    assert one["all"]["poses"] == multi["all"]["poses"] == sum(a["poses"] for a in multi["agents"])
    # and the solve of that same file, by its folder
    optimum = _scores(single, "--estimate", solved[1])
    assert optimum["all"]["ape_translation_m"]["mean"] < 0.5 * one["all"]["ape_translation_m"]["mean"]


def test_bad_hand_offs_are_one_line_each(small, solved, tmp_path):
    lonely = tmp_path / "lonely.g2o"
    shutil.copy(small.single_dir / "Small.g2o", lonely)
    res = runner.invoke(app, ["evaluate", str(lonely)])
    assert res.exit_code == 2 and "lonely_GT.tum" in res.stderr and len(res.stderr.strip().splitlines()) == 1
    bad = tmp_path / "bad"
    shutil.copytree(solved[0], bad)
    record = json.loads((bad / "solve.json").read_text())
    (bad / "solve.json").write_text(json.dumps({**record, "estimate": "../elsewhere"}))
    res = runner.invoke(app, ["evaluate", str(small.dataset_dir), "--estimate", str(bad)])
    assert res.exit_code == 2 and "$.estimate" in res.stderr and len(res.stderr.strip().splitlines()) == 1
    (bad / "solve.json").write_text("{not json")
    res = runner.invoke(app, ["evaluate", str(small.dataset_dir), "--estimate", str(bad)])
    assert res.exit_code == 2 and "solve.json" in res.stderr and "Traceback" not in res.output
