"""`run_viewer` (what `studio view` runs in the foreground) leaves no viewer behind, whenever the
signal that stops it arrives: a SIGTERM while the viewer's process is being started used to be
raised inside ``Popen`` and leave the new process serving with nobody to stop it."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time

import pytest

from studio.recording import viewer

pytestmark = pytest.mark.skipif(sys.platform == "win32", reason="POSIX signals and process groups")

_SLEEPER = [sys.executable, "-c", "import time; time.sleep(60)"]


def _gone(pid: int, timeout_s: float = 10.0) -> bool:
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        try:
            os.kill(pid, 0)
        except ProcessLookupError:
            return True
        time.sleep(0.05)
    return False


def _popen_then_signal(signum: int, seen: list[int]):
    real = subprocess.Popen

    def popen(*args, **kwargs):
        proc = real(*args, **kwargs)
        seen.append(proc.pid)
        os.kill(os.getpid(), signum)  # arrives before Popen has returned to run_viewer
        return proc

    return popen


@pytest.mark.parametrize("signum", [signal.SIGTERM, signal.SIGHUP, signal.SIGINT])
def test_a_signal_while_the_viewer_starts_stops_it(monkeypatch, signum):
    seen: list[int] = []
    monkeypatch.setattr(viewer.subprocess, "Popen", _popen_then_signal(signum, seen))
    before = signal.getsignal(signal.SIGTERM)
    assert viewer.run_viewer(_SLEEPER) == 128 + signum
    assert len(seen) == 1 and _gone(seen[0])
    assert signal.getsignal(signal.SIGTERM) is before  # the handlers are put back


def test_the_viewers_own_exit_code_when_it_ends_by_itself():
    assert viewer.run_viewer([sys.executable, "-c", "raise SystemExit(3)"]) == 3
