"""The benchmarks' one way to time a whole process: wall seconds and peak resident memory.

Peak memory is the kernel's ``ru_maxrss`` of the command and the workers it waited for. That figure
survives ``exec``: a command started directly from this (large) Python process would report at least
this process's own resident size (measured: kollagen's 9.5 MiB read as 30 MiB). So, where GNU time is
installed, the command is started through it: its small process forks the command, and its ``%M`` is
the command's own peak. Without it, the figure is an upper bound and says so (``peak_is_bound``).

Before the first timed run the studio's modules are compiled to bytecode, as ``pip install`` does
(and as the first run of an editable install does). Where ``PYTHONDONTWRITEBYTECODE`` is set (as on
the machine the README's figures come from), every run would otherwise compile all of them again:
about 45 ms per ``studio`` command that no installed copy pays.
"""

from __future__ import annotations

import atexit
import compileall
import importlib.util
import os
import shutil
import subprocess
import tempfile
import time
from pathlib import Path
from typing import Any

_GNU_TIME = next((p for p in ("/usr/bin/time", shutil.which("gtime")) if p and os.access(p, os.X_OK)), None)

#: True when peak memory figures are upper bounds (no GNU time to start commands from a small process).
peak_is_bound = _GNU_TIME is None


_compiled: list[bool] = []


def compile_studio() -> None:
    """Compile the studio's modules (wherever its packages are installed) to bytecode, once."""
    if _compiled:
        return
    for package in ("studio", "studio.generator", "studio.converters"):
        spec = importlib.util.find_spec(package)
        for folder in (spec.submodule_search_locations or []) if spec else []:
            compileall.compile_dir(folder, quiet=1)
    _compiled.append(True)


def run_usage(cmd: list[str], *, shown: list[str] | None = None) -> tuple[float, Any]:
    """Wall seconds and the ``resource.struct_rusage`` of one run of ``cmd`` (the process and the
    workers it waited for). Its stderr goes to a temporary file (never a pipe that could fill while
    this waits), and its tail is shown when the run fails, under the name ``shown`` (default
    ``cmd``). The studio's bytecode is compiled first (:func:`compile_studio`)."""
    compile_studio()
    with tempfile.TemporaryFile() as err:
        t0 = time.perf_counter()
        proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=err)
        _, status, usage = os.wait4(proc.pid, 0)
        wall = time.perf_counter() - t0
        code = os.waitstatus_to_exitcode(status)
        if code:
            err.seek(0)
            tail = err.read().decode(errors="replace")[-500:]
            raise SystemExit(f"{' '.join(shown or cmd)} failed with exit code {code}: {tail}")
    return wall, usage


def run_measured(cmd: list[str]) -> tuple[float, float, float]:
    """Wall seconds, CPU seconds (user + system) and peak RSS (MiB) of one run of ``cmd``
    (:func:`run_usage`): the peak the largest of the process and the workers it waited for, through
    GNU time where installed."""
    if _GNU_TIME is None:
        wall, usage = run_usage(cmd)
        return wall, usage.ru_utime + usage.ru_stime, usage.ru_maxrss / 1024.0
    with tempfile.NamedTemporaryFile("r") as peak_file:
        wall, usage = run_usage([_GNU_TIME, "-f", "%M", "-o", peak_file.name, *cmd], shown=cmd)
        lines = [ln for ln in peak_file.read().split() if ln.strip().isdigit()]
        return wall, usage.ru_utime + usage.ru_stime, int(lines[-1]) / 1024.0


def run_timed(cmd: list[str]) -> tuple[float, float]:
    """Wall seconds and peak RSS (MiB) of one run of ``cmd`` (:func:`run_measured`)."""
    wall, _, peak = run_measured(cmd)
    return wall, peak


def work_folder(out: Path | None) -> Path:
    """The benchmark's work folder: ``out`` (created if missing), or a temporary folder removed when
    the script ends."""
    if out is not None:
        out.mkdir(parents=True, exist_ok=True)
        return out
    tmp = tempfile.mkdtemp(prefix="studio-bench-")
    atexit.register(shutil.rmtree, tmp, True)
    return Path(tmp)
