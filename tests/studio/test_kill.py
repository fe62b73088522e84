"""Kill a running `studio synth`: no target appears, and the next run cleans the staging folder."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time

import pytest

from studio.io.atomic import STAGING_PREFIX


@pytest.mark.parametrize("sig", [signal.SIGKILL, signal.SIGINT])
def test_killed_synth_leaves_no_target(tmp_path, sig):
    out = tmp_path / "out"
    cmd = [sys.executable, "-m", "studio.cli", "synth", "multi10000x5", "-o", str(out), "-q"]
    env = dict(os.environ, CI="true")
    proc = subprocess.Popen(cmd, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    deadline = time.monotonic() + 60
    while time.monotonic() < deadline and not any(out.glob(STAGING_PREFIX + "*")):
        time.sleep(0.01)
    time.sleep(0.3)  # well inside generation or writing
    proc.send_signal(sig)
    proc.communicate(timeout=60)
    assert proc.returncode != 0
    leftovers = sorted(p.name for p in out.iterdir())
    assert not [n for n in leftovers if not n.startswith(STAGING_PREFIX)], leftovers
    if sig == signal.SIGINT:  # an orderly interrupt cleans up itself
        assert leftovers == []
    # the next run in the same folder removes a stale staging folder and succeeds
    done = subprocess.run([sys.executable, "-m", "studio.cli", "synth", str(_tiny()), "-o", str(out), "-q"],
                          env=env, capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    assert sorted(p.name for p in out.iterdir()) == ["tiny_single", "tiny_single.config.json", "tiny_single_singleg2o"]


def _tiny():
    from pathlib import Path

    return Path(__file__).resolve().parent.parent / "data" / "configs" / "tiny_single.json"
