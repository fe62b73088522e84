"""Start-up of the command line (issue 28): how long ``studio`` takes before its work.

    python benchmarks/bench_startup.py [--config tests/data/configs/tiny_three.json] [--repeat 9]

Each run is a whole new process, timed from just before it is spawned (this process's clock, shared
through the environment). For ``studio synth CONFIG -o OUT --no-rrd -q`` the process itself notes two
moments: **cli** when the ``synth`` command's function is entered (Python, site, typer and every
command's option declarations done, the arguments parsed) and **library** when
:func:`studio.synth.synthesize` is entered (the library and numpy imported, the config read); **end**
is the process's exit as this process sees it. ``studio --version`` and ``python -c pass`` (the
interpreter and site alone) are timed whole. The runs are interleaved; medians and bests are printed.

The two moments are noted by a small bootstrap (``-c``) that wraps the two functions when their
modules are loaded (a meta-path hook: no import moves earlier) and runs the console script's entry
point; the studio's code is not changed for it. The output goes to a temporary folder in RAM (/dev/shm)
where there is one. See README, "Start-up".
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from timing import compile_studio

REPO = Path(__file__).resolve().parents[1]

#: Run in the child: wrap the synth command and ``synthesize`` as their modules load, note when each is
#: entered (seconds since the parent's spawn), write the notes at exit, run the console script.
BOOT = r"""
import atexit, functools, importlib.abc, json, os, sys, time
T0 = float(os.environ["STARTUP_T0"])
NOTES = {}
def note(key):
    NOTES.setdefault(key, time.time() - T0)
def wrapped(func, key):
    @functools.wraps(func)
    def call(*args, **kwargs):
        note(key)
        return func(*args, **kwargs)
    return call
def patch_cli(module):
    for info in module.app.registered_commands:
        if info.callback.__name__ == "synth":
            info.callback = wrapped(info.callback, "cli")
def patch_synth(module):
    module.synthesize = wrapped(module.synthesize, "library")
PATCHES = {"studio.cli": patch_cli, "studio.synth": patch_synth}
class Hook(importlib.abc.MetaPathFinder):
    def find_spec(self, name, path, target=None):
        if name not in PATCHES:
            return None
        for finder in sys.meta_path:
            if finder is self:
                continue
            spec = finder.find_spec(name, path, target)
            if spec is not None:
                run = spec.loader.exec_module
                def exec_module(module, run=run, patch=PATCHES[name]):
                    run(module)
                    patch(module)
                spec.loader.exec_module = exec_module
                return spec
        return None
sys.meta_path.insert(0, Hook())
ME = os.getpid()
def dump():
    if os.getpid() == ME:  # not a forked worker
        with open(os.environ["STARTUP_NOTES"], "w") as f:
            f.write(json.dumps(NOTES))
atexit.register(dump)
sys.argv = ["studio", *sys.argv[1:]]
from studio._entry import main
main()
"""


def timed(cmd: list[str], notes: Path | None = None) -> tuple[float, dict[str, float]]:
    env = dict(os.environ, STARTUP_NOTES=str(notes or ""))
    env["STARTUP_T0"] = repr(time.time())  # the child's clock starts here
    t0 = time.perf_counter()
    res = subprocess.run(cmd, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    wall = time.perf_counter() - t0
    if res.returncode:
        shown = " ".join(w for w in cmd if w != BOOT)
        raise SystemExit(f"{shown} failed ({res.returncode}): {res.stderr.decode()[-500:]}")
    return wall, (json.loads(notes.read_text()) if notes else {})


def summary(label: str, values: list[float]) -> str:
    return f"{label:48} median {1e3 * statistics.median(values):6.1f} ms  best {1e3 * min(values):6.1f} ms"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--config", default=str(REPO / "tests" / "data" / "configs" / "tiny_three.json"))
    ap.add_argument("--repeat", type=int, default=9)
    args = ap.parse_args()
    compile_studio()
    studio = shutil.which("studio") or "studio"
    ram = "/dev/shm" if os.path.isdir("/dev/shm") else None
    with tempfile.TemporaryDirectory(dir=ram) as tmp:
        notes = Path(tmp) / "notes.json"
        synth = [sys.executable, "-c", BOOT, "synth", args.config, "-o", f"{tmp}/out", "--force", "--no-rrd", "-q"]
        rows: dict[str, list[float]] = {k: [] for k in ("python", "version", "cli", "library", "end")}
        timed(synth, notes)  # a first run: the page cache warm for every module
        for _ in range(args.repeat):
            rows["python"].append(timed([sys.executable, "-c", "pass"])[0])
            rows["version"].append(timed([studio, "--version"])[0])
            wall, marks = timed(synth, notes)
            rows["cli"].append(marks["cli"])
            rows["library"].append(marks["library"])
            rows["end"].append(wall)
    print(f"load {os.getloadavg()[0]:.2f}; {args.repeat} runs each, interleaved; config {args.config}")
    print(summary("python -c pass (interpreter and site)", rows["python"]))
    print(summary("studio --version", rows["version"]))
    print(summary("studio synth: the synth command entered", rows["cli"]))
    print(summary("studio synth: synthesize() entered", rows["library"]))
    print(summary("studio synth: the process ended (whole command)", rows["end"]))


if __name__ == "__main__":
    main()
