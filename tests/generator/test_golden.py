"""Golden outputs for small configs of our own (checked once against kollagen's C++ build).

They keep the byte-exactness checked on machines without ../shared. Each manifest lists the sha256 of
every file kollagen writes for the config; tiny_single's files are also committed in full.
"""

from __future__ import annotations

import filecmp
import hashlib
from pathlib import Path

import pytest

from studio.synth import load_synth_config, synthesize

DATA = Path(__file__).resolve().parent.parent / "data"
CONFIGS = sorted(p.stem for p in (DATA / "configs").glob("tiny_*.json"))


def _manifest(name: str) -> dict[str, str]:
    out = {}
    for line in (DATA / "golden" / f"{name}.sha256").read_text().splitlines():
        digest, rel = line.split(maxsplit=1)
        out[rel] = digest
    return out


def test_every_tiny_config_has_a_manifest():
    assert CONFIGS == ["tiny_exact_noretro", "tiny_shared_entry", "tiny_single", "tiny_three"]


@pytest.mark.parametrize("name", CONFIGS)
def test_tiny_configs_match_golden_digests(tmp_path, name):
    # rrd=False: these are kollagen's bytes; a recording is compared by content (tests/recording/test_recording.py)
    synthesize(load_synth_config(DATA / "configs" / f"{name}.json"), tmp_path, jobs=1, rrd=False)
    expected = _manifest(name)
    written = sorted(str(p.relative_to(tmp_path)) for p in tmp_path.rglob("*") if p.is_file() and p.suffix != ".json")
    assert written == sorted(expected)
    for rel, digest in expected.items():
        assert hashlib.sha256((tmp_path / rel).read_bytes()).hexdigest() == digest, rel


def test_tiny_single_full_golden_files(tmp_path):
    synthesize(load_synth_config(DATA / "configs" / "tiny_single.json"), tmp_path, rrd=False)
    for rel in _manifest("tiny_single"):
        assert filecmp.cmp(DATA / "golden" / rel, tmp_path / rel, shallow=False), rel


def test_parallel_and_serial_runs_write_the_same_bytes(tmp_path):
    cfg = load_synth_config(DATA / "configs" / "tiny_three.json")
    synthesize(cfg, tmp_path / "serial", jobs=1, rrd=False)
    synthesize(cfg, tmp_path / "parallel", jobs=2, rrd=False)
    files = sorted(p.relative_to(tmp_path / "serial") for p in (tmp_path / "serial").rglob("*") if p.is_file())
    assert len(files) == 11
    for rel in files:
        assert filecmp.cmp(tmp_path / "serial" / rel, tmp_path / "parallel" / rel, shallow=False), rel
