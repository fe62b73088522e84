"""`studio synth` on a busy machine: the parallel path against `--jobs 1`, next to noisy neighbours.

    python benchmarks/bench_busy.py [--preset multi10000x5] [--radius 6] [--repeat 5]
                                    [--neighbours none cpu1 cpu memory disk files mixed] [--jobs 0 2]

For each kind of neighbour, the neighbours are started, left to settle for a second, and then
`studio synth CONFIG -o DIR --no-rrd -q` runs in turn with `--jobs 1`, with each `--jobs J`
(default: 0, what a user gets: the cores not busy at that moment; and 2, always parallel) and with
`--jobs 1` again (row `1*`: the control, whose ratio to the first `--jobs 1` is the noise of the
measurement), --repeat times each; the order of the settings rotates from one repeat to the next,
so that none always runs right after the same one. Neighbours (this script's own small loops, one
per core unless said otherwise):

* cpu1:   one busy Python loop;
* cpu:    busy Python loops;
* memory: numpy processes that allocate, touch and free 512 MiB arrays in a loop (page faults,
          memory bandwidth, the kernel zeroing pages);
* disk:   one process writing 256 MiB files with fsync and deleting them (dirty-page writeback);
* files:  one process creating, fsyncing and deleting many small files (a test corpus);
* mixed:  one of each of the four above.

Prints per neighbour kind and jobs setting the median wall time, CPU time (user + sys of the process
and its workers), minor page faults and involuntary context switches, the ratio parallel / --jobs 1
and the 1-minute load average seen before the runs.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import shutil
import statistics
import subprocess
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from timing import run_usage, work_folder  # noqa: E402  (benchmarks/timing.py, beside this script)

from studio.generator.presets import preset  # noqa: E402
from studio.io.synth_config import synth_config_to_json  # noqa: E402

NEIGHBOUR_CODE = {
    "cpu": "while True:\n    pass\n",
    "memory": (
        "import numpy as np\n"
        "while True:\n"
        "    a = np.ones(64 << 20)\n"  # 512 MiB of float64, touched page by page
        "    a += 1.0\n"
        "    del a\n"
    ),
    "disk": (
        "import os, sys\n"
        "path = os.path.join(sys.argv[1], 'disk.bin')\n"
        "block = os.urandom(1 << 20)\n"
        "while True:\n"
        "    with open(path, 'wb') as f:\n"
        "        for _ in range(256):\n"
        "            f.write(block)\n"
        "        f.flush(); os.fsync(f.fileno())\n"
        "    os.remove(path)\n"
    ),
    "files": (
        "import os, sys\n"
        "folder = sys.argv[1]\n"
        "k = 0\n"
        "while True:\n"
        "    names = []\n"
        "    for i in range(200):\n"
        "        p = os.path.join(folder, f'f{k}_{i}.txt')\n"
        "        with open(p, 'w') as f:\n"
        "            f.write('x' * 4096)\n"
        "            f.flush(); os.fsync(f.fileno())\n"
        "        names.append(p)\n"
        "    for p in names:\n"
        "        os.remove(p)\n"
        "    k += 1\n"
    ),
}


def neighbour_plan(kind: str, cores: int) -> list[str]:
    if kind == "none":
        return []
    if kind == "mixed":
        return ["cpu", "memory", "disk", "files"]
    if kind in ("disk", "files"):
        return [kind]
    if kind == "cpu1":
        return ["cpu"]
    return [kind] * cores


def start_neighbours(kinds: list[str], work: Path) -> list[subprocess.Popen]:
    procs = []
    for i, kind in enumerate(kinds):
        folder = work / f"neighbour{i}"
        folder.mkdir(parents=True, exist_ok=True)
        procs.append(
            subprocess.Popen(
                [sys.executable, "-c", NEIGHBOUR_CODE[kind], str(folder)],
                stdout=subprocess.DEVNULL,
                stderr=subprocess.DEVNULL,
                start_new_session=True,
            )
        )
    return procs


def stop_neighbours(procs: list[subprocess.Popen]) -> None:
    for p in procs:
        p.kill()
    for p in procs:
        p.wait()


def run_once(cmd: list[str]) -> dict[str, float]:
    """Wall seconds and the rusage of one run (the process and every worker it waited for)."""
    wall, usage = run_usage(cmd)
    return {
        "wall": wall,
        "cpu": usage.ru_utime + usage.ru_stime,
        "minflt": usage.ru_minflt,
        "nivcsw": usage.ru_nivcsw,
        "majflt": usage.ru_majflt,
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--preset", default="multi10000x5")
    ap.add_argument(
        "--radius",
        type=float,
        default=6.0,
        help="loop-closure radius [m], intra and inter (the preset's with 0; default 6)",
    )
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument(
        "--jobs",
        type=int,
        nargs="+",
        default=[0, 2],
        help="the settings compared with --jobs 1 (0: the default, the idle cores)",
    )
    kinds = ["none", "cpu1", "cpu", "memory", "disk", "files", "mixed"]
    ap.add_argument("--neighbours", nargs="*", default=kinds, choices=kinds)
    ap.add_argument("--out", type=Path, default=None, help="work folder (default: a temporary folder, removed after)")
    args = ap.parse_args()
    studio = shutil.which("studio") or str(Path(sys.executable).parent / "studio")
    cores = len(os.sched_getaffinity(0))
    doc = synth_config_to_json(preset(args.preset))
    if args.radius > 0:
        for spec in doc["agent_parameters"]["agent_specific"]:
            spec["intra_loop_closure_radius"] = args.radius
        doc["inter_agent_loop_closure_parameters"]["loop_closure_radius"] = args.radius
    print(
        f"# {time.strftime('%Y-%m-%d %H:%M')}  {cores} cores  python {sys.version.split()[0]}  "
        f"{args.preset} R={args.radius:g} m  --jobs 1 vs --jobs {' / '.join(map(str, args.jobs))}"
    )
    print(f"{'neighbours':10} {'jobs':>4} {'load':>5} {'wall s':>7} {'cpu s':>6} {'minflt':>8} {'invcsw':>7}  ratio")
    work = work_folder(args.out)
    cfg = work / "busy.json"
    cfg.write_text(json.dumps(doc, indent=2))
    for kind in args.neighbours:
        procs = start_neighbours(neighbour_plan(kind, cores), work)
        try:
            time.sleep(1.0)
            load = os.getloadavg()[0]
            # (label, --jobs): the reference, the settings compared with it, the control
            settings = [("1", 1), *[(str(j), j) for j in args.jobs if j != 1], ("1*", 1)]
            rows: dict[str, list[dict[str, float]]] = {label: [] for label, _ in settings}
            for k in range(args.repeat):
                for label, jobs in settings[k % len(settings) :] + settings[: k % len(settings)]:
                    out = work / f"run_{kind}_{jobs}_{k}"
                    rows[label].append(
                        run_once([studio, "synth", str(cfg), "-o", str(out), "--no-rrd", "-q", "--jobs", str(jobs)])
                    )
                    shutil.rmtree(out)
        finally:
            stop_neighbours(procs)
            for p in work.glob("neighbour*"):
                shutil.rmtree(p, ignore_errors=True)
        med = {label: {key: statistics.median(r[key] for r in runs) for key in runs[0]} for label, runs in rows.items()}
        for label, _ in settings:
            m = med[label]
            ratio = f"{m['wall'] / med['1']['wall']:.2f}x" if label != "1" else ""
            print(
                f"{kind:10} {label:>4} {load:5.1f} {m['wall']:7.2f} {m['cpu']:6.2f} {m['minflt']:8.0f} "
                f"{m['nivcsw']:7.0f}  {ratio}",
                flush=True,
            )
        time.sleep(2.0)


if __name__ == "__main__":
    resource.setrlimit(resource.RLIMIT_CORE, (0, 0))
    main()
