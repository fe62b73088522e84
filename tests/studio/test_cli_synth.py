"""`studio synth` end to end through the CLI: outputs, refusals and bad input."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from typer.testing import CliRunner

import studio.synth as synth_module
from studio.cli import app
from studio.io.atomic import STAGING_PREFIX

DATA = Path(__file__).resolve().parent.parent / "data"
runner = CliRunner()


def _config() -> dict:
    return json.loads((DATA / "configs" / "tiny_three.json").read_text())


def _write(tmp_path: Path, data, name: str = "cfg") -> Path:
    path = tmp_path / f"{name}.json"
    path.write_text(data if isinstance(data, str) else json.dumps(data))
    return path


def _run(*args):
    return runner.invoke(app, ["synth", *map(str, args)])


def test_synth_writes_kollagens_layout(tmp_path):
    cfg = _write(tmp_path, _config(), "mine")
    out = tmp_path / "out"
    res = _run(cfg, "-o", out)
    assert res.exit_code == 0, res.output
    assert "3 agents, 723 poses" in res.output
    names = sorted(p.name for p in out.iterdir())
    assert names == ["mine", "mine.config.json", "mine.rrd", "mine_singleg2o"]
    assert sorted(p.name for p in (out / "mine").iterdir()) == ["agent1", "agent2", "agent3", "inter_agent_lc.dat"]
    assert sorted(p.name for p in (out / "mine_singleg2o").iterdir()) == ["mine.g2o", "mine.tum", "mine_GT.tum"]
    # the effective config regenerates the same dataset
    again = _run(out / "mine.config.json", "-o", tmp_path / "again")
    assert again.exit_code == 0
    a = (out / "mine" / "agent2" / "posegraph.g2o").read_bytes()
    assert a == (tmp_path / "again" / "mine" / "agent2" / "posegraph.g2o").read_bytes()


def test_record_kind_options(tmp_path):
    cfg = _write(tmp_path, _config(), "c")
    res = _run(cfg, "-o", tmp_path / "o", "--multi-records", "2d", "--single-records", "3d")
    assert res.exit_code == 0, res.output
    multi = (tmp_path / "o" / "c" / "agent1" / "posegraph.g2o").read_text()
    single = (tmp_path / "o" / "c_singleg2o" / "c.g2o").read_text()
    assert multi.startswith("VERTEX_SE2 0 0 0 0\n")
    assert single.startswith("VERTEX_SE3:QUAT 0 0 0 0.0 0.0 0.0 0 1\n")


def test_existing_output_needs_force(tmp_path):
    cfg = _write(tmp_path, _config(), "c")
    out = tmp_path / "o"
    assert _run(cfg, "-o", out).exit_code == 0
    marker = out / "c" / "agent1" / "posegraph.g2o"
    marker.write_text("hand edit\n")
    res = _run(cfg, "-o", out)
    assert res.exit_code == 2
    assert "already exists (use --force to overwrite)" in res.stderr
    assert marker.read_text() == "hand edit\n"
    res = _run(cfg, "-o", out, "--force")
    assert res.exit_code == 0
    assert marker.read_text().startswith("VERTEX_SE3:QUAT 0 ")
    assert not [p for p in out.iterdir() if p.name.startswith(STAGING_PREFIX)]


def test_interrupted_run_leaves_nothing(tmp_path, monkeypatch):
    def boom(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr(synth_module, "write_single_tum", boom)
    cfg = synth_module.load_synth_config(DATA / "configs" / "tiny_three.json")
    with pytest.raises(KeyboardInterrupt):
        synth_module.synthesize(cfg, tmp_path / "o", jobs=1)
    assert list((tmp_path / "o").iterdir()) == []


def test_preset_name_and_unknown_preset(tmp_path):
    res = _run("multi1x1", "-o", tmp_path)
    assert res.exit_code == 2
    assert (
        res.stderr.strip()
        == "error: multi1x1: no such file, and not a preset (presets: cube3d, multi10000x5, multi3500x8, multi3500x8_outliers)"
    )


def _mutate(path: str, value):
    data = _config()
    keys = path.replace("[", ".").replace("]", "").split(".")
    obj = data
    for k in keys[:-1]:
        obj = obj[int(k)] if k.isdigit() else obj[k]
    last = keys[-1]
    if value is KeyError:
        del obj[last]
    else:
        obj[int(last) if last.isdigit() else last] = value
    return data


BAD = [
    (
        "missing key",
        _mutate("agent_parameters.agent_specific[2].std_dev_angle", KeyError),
        "agent_parameters.agent_specific[2].std_dev_angle: missing key",
    ),
    (
        "mistyped key",
        _mutate("agent_parameters.agent_specific[1].std_dev_angle", "0.1"),
        "agent_parameters.agent_specific[1].std_dev_angle: must be a number, got the string '0.1'",
    ),
    (
        "negative std dev",
        _mutate("inter_agent_loop_closure_parameters.std_dev_loop_closure_position", -0.1),
        "inter_agent_loop_closure_parameters.std_dev_loop_closure_position: a standard deviation cannot be "
        "negative, got -0.1",
    ),
    (
        "agent_specific count",
        _mutate("number_of_agents", 2),
        "agent_parameters.agent_specific: has 3 entries; it needs 1 (shared by all agents) or number_of_agents = 2",
    ),
    ("zero agents", _mutate("number_of_agents", 0), "number_of_agents: must be at least 1, got 0"),
    ("negative agents", _mutate("number_of_agents", -3), "number_of_agents: must be at least 1, got -3"),
    ("zero steps", _mutate("number_of_steps", 0), "number_of_steps: must be at least 1, got 0"),
    ("fractional steps", _mutate("number_of_steps", 2.5), "number_of_steps: must be an integer, got 2.5"),
    ("zero stepsize", _mutate("agent_parameters.stepsize", 0), "agent_parameters.stepsize: must be positive, got 0.0"),
    (
        "negative stepsize",
        _mutate("agent_parameters.stepsize", -1.0),
        "agent_parameters.stepsize: must be positive, got -1.0",
    ),
    ("negative steps", _mutate("number_of_steps", -5), "number_of_steps: must be at least 1, got -5"),
    (
        "negative step fragment",
        _mutate("agent_parameters.step_fragment", -2),
        "agent_parameters.step_fragment: must be at least 1, got -2",
    ),
    (
        "steps beyond int",
        _mutate("number_of_steps", 10**13),
        "number_of_steps: 10000000000000 does not fit kollagen's 32-bit int",
    ),
    (
        "zero step fragment",
        _mutate("agent_parameters.step_fragment", 0),
        "agent_parameters.step_fragment: must be at least 1, got 0",
    ),
    ("bool as number", _mutate("align", 1), "align: must be true or false, got the number 1"),
    ("not an object", [1, 2, 3], "must be a JSON object, got an array"),
    (
        "agent entry not an object",
        _mutate("agent_parameters.agent_specific[0]", 5),
        "agent_parameters.agent_specific[0]: must be a JSON object, got the number 5",
    ),
]


@pytest.mark.parametrize(("label", "data", "message"), BAD, ids=[b[0] for b in BAD])
def test_bad_config_one_line_exit_2_nothing_written(tmp_path, label, data, message):
    cfg = _write(tmp_path, data)
    out = tmp_path / "out"
    res = _run(cfg, "-o", out)
    assert res.exit_code == 2
    lines = res.stderr.splitlines()
    assert len(lines) == 1, res.stderr
    assert lines[0] == f"error: {cfg}: {message}"
    assert "Traceback" not in res.output
    assert not out.exists()


def test_missing_file(tmp_path):
    res = _run(tmp_path / "nope.json", "-o", tmp_path / "out")
    assert res.exit_code == 2
    assert "nope.json: no such file, and not a preset" in res.stderr
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize(
    ("text", "where"),
    [
        (
            '{\n  "number_of_steps": 3,\n  oops\n}',
            ":3:3: invalid JSON: Expecting property name enclosed in double quotes",
        ),
        ("", ":1:1: invalid JSON: Expecting value"),
        ('{"a": NaN}', ":1:7: invalid JSON: NaN is not valid JSON"),
        ("[" * 100000, ""),
    ],
)
def test_invalid_json(tmp_path, text, where):
    cfg = _write(tmp_path, text)
    res = _run(cfg, "-o", tmp_path / "out")
    assert res.exit_code == 2
    assert len(res.stderr.splitlines()) == 1
    assert res.stderr.startswith(f"error: {cfg}{where}")
    assert not (tmp_path / "out").exists()


def test_unknown_key_warns_with_hint(tmp_path):
    data = _config()
    data["agent_parameters"]["stepsise"] = 1.0
    res = _run(_write(tmp_path, data), "-o", tmp_path / "out")
    assert res.exit_code == 0
    assert "agent_parameters.stepsise: unknown key, ignored (did you mean 'stepsize'?)" in res.stderr


def test_exact_information_needs_positive_noise(tmp_path):
    data = _mutate("agent_parameters.agent_specific[0].std_dev_angle", 0.0)
    data["exact_information_matrix"] = True
    res = _run(_write(tmp_path, data), "-o", tmp_path / "out")
    assert res.exit_code == 2
    assert (
        "agent_parameters.agent_specific[0].std_dev_angle: must be positive when exact_information_matrix" in res.stderr
    )


def test_resource_guard_refuses_huge_configs_before_any_work(tmp_path):
    data = _mutate("number_of_steps", 2 * 10**9)
    cfg = _write(tmp_path, data, "huge")
    res = _run(cfg, "-o", tmp_path / "out")
    assert res.exit_code == 2
    assert res.stderr.strip() == (  # the config's file, not only its name (issue 41)
        f"error: {cfg}: 2.4e+10 poses and their loop-closure radii would need about 7.32e+05 GB of memory, "
        "over the 8 GB limit (raise it with --max-memory-gb)"
    )
    assert not (tmp_path / "out").exists()
    res = _run(
        _write(tmp_path, _mutate("number_of_steps", 2 * 10**6), "big"), "-o", tmp_path / "out", "--max-memory-gb", "1e9"
    )
    assert res.exit_code == 2
    assert "would write about 36 GB, over the 20 GB limit (raise it with --max-output-gb)" in res.stderr


def test_resource_guard_counts_the_loop_closure_circle(tmp_path):
    # 1e4 m at 4 cells per metre: a circle of 1.3e9 cells; refused at once instead of hanging
    data = _mutate("agent_parameters.agent_specific[1].intra_loop_closure_radius", 1e4)
    cfg = _write(tmp_path, data, "wide")
    res = _run(cfg, "-o", tmp_path / "out")
    assert res.exit_code == 2
    assert res.stderr.startswith(f"error: {cfg}: 723 poses and their loop-closure radii would need about ")
    assert res.stderr.rstrip().endswith("GB limit (raise it with --max-memory-gb)")
    assert not (tmp_path / "out").exists()


def test_a_file_named_like_a_preset_is_used_but_never_silently(tmp_path, monkeypatch):
    """A folder of samples or stand-ins holding a file `multi3500x8` used to turn `studio synth
    multi3500x8` into that file's 3-agent toy without a word; now the warning says which was used."""
    from studio.synth import load_synth_config, shadowed_preset

    monkeypatch.chdir(tmp_path)
    assert shadowed_preset("multi3500x8") is None  # no such file here: the preset, nothing to say
    assert load_synth_config("multi3500x8").number_of_agents == 8
    (tmp_path / "multi3500x8").write_text(json.dumps(_config()))
    res = CliRunner().invoke(app, ["synth", "multi3500x8", "-o", "out", "--no-rrd"])
    assert res.exit_code == 0, res.output
    assert "multi3500x8: 3 agents" in res.output
    assert res.stderr == (
        f"warning: multi3500x8: using the file {tmp_path / 'multi3500x8'}, not the preset of that name "
        "(run from another folder, or rename the file, to get the preset)\n"
    )
    # the library says it too: through its warn callback, else Python's warnings
    said: list[str] = []
    assert load_synth_config("multi3500x8", warn=said.append).number_of_agents == 3
    assert said == [shadowed_preset("multi3500x8")]
    with pytest.warns(UserWarning, match="using the file .*multi3500x8, not the preset"):
        load_synth_config("multi3500x8")
