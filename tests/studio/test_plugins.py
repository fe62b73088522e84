"""Plug-ins from other packages (issue 38): the example package of examples/studio-plugin-example,
made visible as an installed package is (a ``.dist-info`` with its ``entry_points.txt``, written
from the example's own pyproject.toml, on the path of a fresh interpreter), is listed by
``studio plugins`` and the commands' --help without being imported, replays and solves; a plug-in
that fails to import is one line naming it, exit 2, nothing written."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

try:
    import tomllib
except ModuleNotFoundError:  # Python 3.10
    import tomli as tomllib

from studio.synth import load_synth_config, synthesize

ROOT = Path(__file__).resolve().parents[2]
EXAMPLE = ROOT / "examples" / "studio-plugin-example"
DATA = ROOT / "tests" / "data"


def _install(site: Path, entry_points: dict[str, dict[str, str]], name: str = "studio-plugin-example") -> None:
    """What ``pip install`` leaves of a package's metadata: a .dist-info with its entry points."""
    info = site / f"{name.replace('-', '_')}-0.1.0.dist-info"
    info.mkdir(parents=True)
    (info / "METADATA").write_text(f"Metadata-Version: 2.1\nName: {name}\nVersion: 0.1.0\n", encoding="utf-8")
    text = "".join(
        f"[{group}]\n" + "".join(f"{k} = {v}\n" for k, v in names.items()) + "\n"
        for group, names in entry_points.items()
    )
    (info / "entry_points.txt").write_text(text, encoding="utf-8")


def _studio(site: Path, *args: str) -> subprocess.CompletedProcess[str]:
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(site), str(EXAMPLE)]))
    return subprocess.run([sys.executable, "-m", "studio", *args], capture_output=True, text=True, env=env, timeout=300)


@pytest.fixture(scope="module")
def example_site(tmp_path_factory) -> Path:
    site = tmp_path_factory.mktemp("site")
    declared = tomllib.loads((EXAMPLE / "pyproject.toml").read_text(encoding="utf-8"))["project"]["entry-points"]
    _install(site, declared)
    return site


@pytest.fixture(scope="module")
def tiny(tmp_path_factory):
    root = tmp_path_factory.mktemp("plug-data")
    return synthesize(load_synth_config(DATA / "configs" / "tiny_three.json"), root, rrd=False, jobs=1).dataset_dir


def test_the_example_is_small():
    lines = sum(len(p.read_text(encoding="utf-8").splitlines()) for p in EXAMPLE.iterdir() if p.is_file())
    assert lines < 100


def test_plugins_are_listed_without_being_imported(example_site):
    res = _studio(example_site, "plugins")
    assert res.returncode == 0, res.stderr
    assert "example-odometry  studio_plugin_example:OdometryBackend  from studio-plugin-example 0.1.0" in res.stdout
    assert "example-odometry  studio_plugin_example:METHOD  from studio-plugin-example 0.1.0" in res.stdout
    for command, option in (("replay", "--backend"), ("solve", "--method")):
        res = _studio(example_site, command, "--help")
        help_text = " ".join(res.stdout.split())
        assert "example-odometry" in help_text.replace("example- odometry", "example-odometry"), (command, option)
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(example_site), str(EXAMPLE)]))
    probe = "import sys, studio.cli; print('studio_plugin_example' in sys.modules, 'numpy' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, env=env, timeout=120)
    assert out.stdout.split() == ["False", "False"], out.stderr


def test_the_example_backend_replays_and_the_method_solves(example_site, tiny, tmp_path):
    res = _studio(example_site, "replay", str(tiny), "-b", "example-odometry,centralized", "-o", str(tmp_path / "r"))
    assert res.returncode == 0, res.stderr
    rows = (tmp_path / "r" / "summary.csv").read_text(encoding="utf-8").splitlines()
    plug, central = (dict(zip(rows[0].split(","), r.split(","))) for r in rows[1:])
    assert plug["backend"] == "example-odometry" and plug["messages"] == "0"
    assert float(plug["ape_se3_m"]) > 2 * float(central["ape_se3_m"]) > 0  # dead reckoning loses to optimization
    assert (tmp_path / "r" / "example-odometry.jrr").is_file()
    res = _studio(example_site, "solve", str(tiny), "--method", "example-odometry", "-o", str(tmp_path / "s"))
    assert res.returncode == 0, res.stderr
    assert "example-odometry, 0 iterations" in res.stdout


def test_the_example_methods_own_option_reaches_it_by_name(example_site, tiny, tmp_path):
    """A plug-in method's own options are the fields of the class its entry names: set by name from
    Python, refused by name where the method does not read them; `studio solve` has no flag for
    them (the command line is built without importing plug-ins), so a typed dgs flag is refused."""
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(example_site), str(EXAMPLE)]))
    script = (
        "import json, sys\n"
        "from studio.core.errors import ConfigError\n"
        "from studio.solve import solve\n"
        f"res = solve({str(tiny)!r}, {str(tmp_path / 'lib')!r}, method='example-odometry', label='run 3')\n"
        "print(json.dumps([res.solution.notes['label'], res.to_dict()['options']['label']]))\n"
        "try:\n"
        f"    solve({str(tiny)!r}, {str(tmp_path / 'bad')!r}, method='example-odometry', robots=2)\n"
        "except ConfigError as err:\n"
        "    print(err)\n"
    )
    out = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, env=env, timeout=300)
    assert out.returncode == 0, out.stderr
    assert out.stdout.splitlines() == [
        '["run 3", "run 3"]',
        "robots: method example-odometry does not read it (it reads label)",
    ]
    res = _studio(
        example_site, "solve", str(tiny), "-m", "example-odometry", "--robots", "2", "-o", str(tmp_path / "c")
    )
    assert res.returncode == 2 and res.stderr.startswith("error: --robots: method example-odometry does not read it")
    assert not (tmp_path / "bad").exists() and not (tmp_path / "c").exists()


def test_a_plugin_that_fails_to_import_is_one_line(tmp_path, tiny):
    site = tmp_path / "site"
    _install(
        site,
        {"studio.replay_backends": {"broken": "no_such_module_xyz:B"}, "studio.solve_methods": {"broken": "json:nope"}},
        name="broken-plugin",
    )
    res = _studio(site, "replay", str(tiny), "-b", "broken", "-o", str(tmp_path / "r"))
    assert res.returncode == 2 and "Traceback" not in res.stderr
    assert res.stderr.splitlines()[0] == (
        "error: replay back-end plug-in 'broken' (no_such_module_xyz:B, from broken-plugin 0.1.0) failed to load: "
        "ModuleNotFoundError: No module named 'no_such_module_xyz'"
    )
    res = _studio(site, "solve", str(tiny), "--method", "broken", "-o", str(tmp_path / "s"))
    assert res.returncode == 2 and "Traceback" not in res.stderr
    assert res.stderr.startswith("error: solve method plug-in 'broken' (json:nope, from broken-plugin 0.1.0)")
    assert not (tmp_path / "r").exists() and not (tmp_path / "s").exists()


def test_an_unknown_backend_names_the_plugins_and_command(example_site, tiny, tmp_path):
    res = _studio(example_site, "replay", str(tiny), "-b", "nope", "-o", str(tmp_path / "r"))
    assert res.returncode == 2
    assert "known: centralized, independent, swarm, dgs, example-odometry, command:PROGRAM)" in res.stderr
