"""Kill a running command: no target appears, and the next run cleans the staging folder.

Each job is killed while its outputs are being written (once its staging folder exists).
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from studio.io.atomic import STAGING_PREFIX

DATA = Path(__file__).resolve().parent.parent / "data"
ENV = dict(os.environ, CI="true")


def _studio(*args) -> list[str]:
    return [sys.executable, "-m", "studio.cli", *map(str, args)]


def _kill_while_staging(cmd: list[str], parent: Path, sig: int, delay_s: float = 0.0) -> list[str]:
    """Run ``cmd``, send ``sig`` once a staging folder shows up in ``parent``; return what is left."""
    proc = subprocess.Popen(cmd, env=ENV, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline and proc.poll() is None:
        if parent.is_dir() and any(parent.glob(STAGING_PREFIX + "*")):
            break
        time.sleep(0.005)
    assert proc.poll() is None, "the job ended before it could be killed"
    time.sleep(delay_s)
    proc.send_signal(sig)
    proc.communicate(timeout=60)
    assert proc.returncode != 0
    return sorted(p.name for p in parent.iterdir())


def _assert_clean(leftovers: list[str], sig: int, keep: set[str] = frozenset()) -> None:
    assert not [n for n in leftovers if not n.startswith(STAGING_PREFIX) and n not in keep], leftovers
    if sig == signal.SIGINT:  # an orderly interrupt cleans up itself
        assert [n for n in leftovers if n not in keep] == []


@pytest.mark.parametrize("sig", [signal.SIGKILL, signal.SIGINT])
def test_killed_synth_leaves_no_target(tmp_path, sig):
    out = tmp_path / "out"
    leftovers = _kill_while_staging(_studio("synth", "multi10000x5", "-o", out, "-q"), out, sig, 0.3)
    _assert_clean(leftovers, sig)
    # the next run in the same folder removes a stale staging folder and succeeds
    done = subprocess.run(
        _studio("synth", DATA / "configs" / "tiny_single.json", "-o", out, "-q"),
        env=ENV,
        capture_output=True,
        text=True,
    )
    assert done.returncode == 0, done.stderr
    assert sorted(p.name for p in out.iterdir()) == [
        "tiny_single",
        "tiny_single.config.json",
        "tiny_single.rrd",
        "tiny_single_singleg2o",
    ]


@pytest.fixture(scope="module")
def big_dataset(tmp_path_factory) -> Path:
    from studio.generator.presets import preset
    from studio.synth import synthesize

    root = tmp_path_factory.mktemp("big")
    return synthesize(preset("multi10000x5"), root, rrd=False).dataset_dir


@pytest.mark.slow
@pytest.mark.parametrize("sig", [signal.SIGKILL, signal.SIGINT])
def test_killed_record_leaves_no_recording(tmp_path, big_dataset, sig):
    out = tmp_path / "rec"
    out.mkdir()
    leftovers = _kill_while_staging(_studio("record", big_dataset, "-o", out / "big.rrd", "-q"), out, sig)
    _assert_clean(leftovers, sig)
    done = subprocess.run(
        _studio("record", DATA / "golden" / "tiny_single", "-o", out / "t.rrd", "-q"),
        env=ENV,
        capture_output=True,
        text=True,
    )
    assert done.returncode == 0, done.stderr
    assert sorted(p.name for p in out.iterdir()) == ["t.rrd"]


@pytest.fixture(scope="module")
def big_tum(tmp_path_factory) -> list[Path]:
    root = tmp_path_factory.mktemp("tum")
    files = []
    for k in range(3):
        n = 150_000
        t = np.arange(n)
        ang = 2 * np.pi * 20 * t / n + k
        rows = np.column_stack(
            [
                1_600_000_000 + t * 0.01,
                30 * np.cos(ang),
                30 * np.sin(ang),
                np.zeros(n),
                np.zeros(n),
                np.zeros(n),
                np.sin((ang + np.pi / 2) / 2),
                np.cos((ang + np.pi / 2) / 2),
            ]
        )
        path = root / f"robot{k}.txt"
        np.savetxt(path, rows, fmt=["%.2f"] + ["%.9f"] * 7)
        files.append(path)
    return files


@pytest.mark.slow
@pytest.mark.parametrize("sig", [signal.SIGKILL, signal.SIGINT])
def test_killed_convert_leaves_no_dataset(tmp_path, big_tum, sig):
    parent = tmp_path / "conv"
    parent.mkdir()
    leftovers = _kill_while_staging(_studio("convert", "tum", *big_tum, "-o", parent / "ds", "-q"), parent, sig)
    _assert_clean(leftovers, sig)
    done = subprocess.run(
        _studio("convert", "tum", DATA / "trajectories" / "alpha.tum", "-o", parent / "ok", "-q"),
        env=ENV,
        capture_output=True,
        text=True,
    )
    assert done.returncode == 0, done.stderr
    assert sorted(p.name for p in parent.iterdir()) == ["ok"]
