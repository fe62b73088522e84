"""The benchmarks' one way to time a whole process: wall seconds and peak resident memory."""

from __future__ import annotations

import os
import subprocess
import tempfile
import time


def run_timed(cmd: list[str]) -> tuple[float, float]:
    """Wall seconds and peak RSS (MiB) of one run of ``cmd``: the largest of the process and the
    workers it waited for. Its stderr goes to a temporary file (never a pipe that could fill while
    this waits), and its tail is shown when the run fails."""
    with tempfile.TemporaryFile() as err:
        t0 = time.perf_counter()
        proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=err)
        _, status, usage = os.wait4(proc.pid, 0)
        wall = time.perf_counter() - t0
        code = os.waitstatus_to_exitcode(status)
        if code:
            err.seek(0)
            tail = err.read().decode(errors="replace")[-500:]
            raise SystemExit(f"{' '.join(cmd)} failed with exit code {code}: {tail}")
    return wall, usage.ru_maxrss / 1024.0
