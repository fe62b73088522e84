"""`studio samples DIR`: every source's layout, from any folder, under names no preset has."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest
from typer.testing import CliRunner

from studio.cli import app
from studio.converters.registry import detect_sources
from studio.core.preset_names import PRESET_NAMES
from studio.samples import SAMPLES, write_samples
from studio.synth import shadowed_preset


@pytest.fixture(scope="module")
def folder(tmp_path_factory) -> Path:
    """The samples, written by the installed command from a folder outside the repository (the old
    `python -m tests.samples` failed there: "No module named 'tests'")."""
    root = tmp_path_factory.mktemp("elsewhere")
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    proc = subprocess.run(
        [sys.executable, "-m", "studio", "samples", "mine"], cwd=root, env=env, capture_output=True, text=True
    )
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.splitlines()[0] == "mine: 18 samples"
    return root / "mine"


def test_every_sample_is_written_under_the_names_it_declares(folder):
    declared = sorted(n for names, _ in SAMPLES.values() for n in names)
    assert sorted(p.name for p in folder.iterdir() if not p.name.startswith(".")) == declared


def test_each_source_recognises_its_sample(folder):
    expected = {
        "alpha.txt": "tum",
        "S3E_Square_1": "s3e",
        "run.bag": "bag",
        "s3e_bag": "bag",
        "MH_01_easy": "euroc",
        "poses/00.txt": "kitti",
        "ground_truth/1014": "kimera-multi",
        "MRCLAM_Dataset1": "mrclam",
        "single_robot.g2o": "g2o",
    }
    for name, source in expected.items():
        assert detect_sources(folder / name) == [source], name
    # the AirMuseum sample is one robot folder per robot, which its reader takes when named (detect
    # claims only the published data/<robot>/body_stamped_groundtruth.txt layout)
    from studio.converters.airmuseum import read_airmuseum

    assert [t.name for t in read_airmuseum([folder / "AirMuseum_seq"])] == ["drone", "robot_1", "robot_2", "robot_3"]


def test_no_sample_shadows_a_preset(folder, monkeypatch):
    """`studio synth multi3500x8` inside the samples folder is the preset, not a stand-in."""
    names = {n.lower() for ns, _ in SAMPLES.values() for n in ns}
    assert not names & {p.lower() for p in PRESET_NAMES}
    monkeypatch.chdir(folder)
    assert all(shadowed_preset(p) is None for p in PRESET_NAMES)


def test_the_same_samples_every_time(folder, tmp_path):
    write_samples(tmp_path / "again")
    for path in sorted(folder.rglob("*")):
        if path.is_file() and not path.name.startswith("."):
            assert (tmp_path / "again" / path.relative_to(folder)).read_bytes() == path.read_bytes(), path


def test_an_existing_folder_is_refused_and_left_alone(tmp_path):
    (tmp_path / "mine").mkdir()
    (tmp_path / "mine" / "keep.txt").write_text("mine\n")
    res = CliRunner().invoke(app, ["samples", str(tmp_path / "mine")])
    assert res.exit_code == 2
    assert res.output == f"error: {tmp_path / 'mine'} already exists (use --force to overwrite)\n"
    assert sorted(p.name for p in tmp_path.rglob("*")) == ["keep.txt", "mine"]
