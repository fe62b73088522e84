"""The benchmarks' one way to time a whole process: wall seconds and peak resident memory.

Peak memory is the kernel's ``ru_maxrss`` of the command and the workers it waited for. That figure
survives ``exec``: a command started directly from this (large) Python process would report at least
this process's own resident size (measured: kollagen's 9.5 MiB read as 30 MiB). So, where GNU time is
installed, the command is started through it: its small process forks the command, and its ``%M`` is
the command's own peak. Without it, the figure is an upper bound and says so (``peak_is_bound``).
"""

from __future__ import annotations

import atexit
import os
import shutil
import subprocess
import tempfile
import time
from pathlib import Path

_GNU_TIME = next((p for p in ("/usr/bin/time", shutil.which("gtime")) if p and os.access(p, os.X_OK)), None)

#: True when peak memory figures are upper bounds (no GNU time to start commands from a small process).
peak_is_bound = _GNU_TIME is None


def run_timed(cmd: list[str]) -> tuple[float, float]:
    """Wall seconds and peak RSS (MiB) of one run of ``cmd``: the largest of the process and the
    workers it waited for. Its stderr goes to a temporary file (never a pipe that could fill while
    this waits), and its tail is shown when the run fails."""
    with tempfile.TemporaryFile() as err, tempfile.NamedTemporaryFile("r") as peak_file:
        full = [_GNU_TIME, "-f", "%M", "-o", peak_file.name, *cmd] if _GNU_TIME else cmd
        t0 = time.perf_counter()
        proc = subprocess.Popen(full, stdout=subprocess.DEVNULL, stderr=err)
        _, status, usage = os.wait4(proc.pid, 0)
        wall = time.perf_counter() - t0
        code = os.waitstatus_to_exitcode(status)
        if code:
            err.seek(0)
            tail = err.read().decode(errors="replace")[-500:]
            raise SystemExit(f"{' '.join(cmd)} failed with exit code {code}: {tail}")
        if _GNU_TIME:
            lines = [ln for ln in peak_file.read().split() if ln.strip().isdigit()]
            return wall, int(lines[-1]) / 1024.0
    return wall, usage.ru_maxrss / 1024.0


def work_folder(out: Path | None) -> Path:
    """The benchmark's work folder: ``out`` (created if missing), or a temporary folder removed when
    the script ends."""
    if out is not None:
        out.mkdir(parents=True, exist_ok=True)
        return out
    tmp = tempfile.mkdtemp(prefix="studio-bench-")
    atexit.register(shutil.rmtree, tmp, True)
    return Path(tmp)
