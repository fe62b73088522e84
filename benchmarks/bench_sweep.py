"""`studio sweep` on the local Dask cluster against a sequential loop of CLI calls.

    python benchmarks/bench_sweep.py [--cells 200] [--workers 2] [--config tests/data/configs/tiny_three.json] [--out DIR]

Makes CELLS small datasets (the config with replicate seeds 0..CELLS-1) and evaluates each, once
with `studio sweep` (steps: evaluate) and once as a loop of `studio synth ... && studio evaluate ...`
processes, and prints both wall times, the speed-up and the per-cell overhead of the sweep (its wall
time per cell minus the cell's own work, as measured inside the cells), the 1-minute load average
before and after each phase (the machine is shared), and the peak RSS of the largest process.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import shutil
import subprocess
import sys
import time
from pathlib import Path

from timing import work_folder  # benchmarks/timing.py, beside this script

REPO = Path(__file__).resolve().parent.parent


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--cells", type=int, default=200, help="datasets to make (default 200)")
    ap.add_argument("--workers", type=int, default=2, help="local Dask workers (default 2)")
    ap.add_argument(
        "--config",
        type=Path,
        default=REPO / "tests" / "data" / "configs" / "tiny_three.json",
        help="kollagen JSON of one dataset",
    )
    ap.add_argument("--out", type=Path, default=None, help="work folder (default: a temporary folder)")
    ap.add_argument("--sweep-only", action="store_true", help="time the sweep alone (no loop of CLI calls)")
    args = ap.parse_args()
    studio = shutil.which("studio") or str(Path(sys.executable).parent / "studio")
    work = work_folder(args.out)
    spec = work / "bench.toml"
    spec.write_text(
        f'name = "bench"\nbase = "{args.config.resolve()}"\nsteps = ["evaluate"]\n'
        f"[grid]\nseed = {list(range(args.cells))}\n"
    )
    print(
        f"# {time.strftime('%Y-%m-%d')}  {os.cpu_count()} cores  python {sys.version.split()[0]}  "
        f"load {os.getloadavg()[0]:.2f}  {args.cells} cells of {args.config.name}"
    )
    load0 = os.getloadavg()[0]
    t0 = time.perf_counter()
    subprocess.run(
        [studio, "sweep", str(spec), "-o", str(work / "sweep"), "--workers", str(args.workers), "-q"], check=True
    )
    t_sweep = time.perf_counter() - t0
    load_sweep = (load0, os.getloadavg()[0])
    # the largest process of the sweep (client or a worker: all are reaped descendants by now), in MB
    rss_sweep = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1024
    rows = [json.loads(p.read_text()) for p in (work / "sweep" / "cells").glob("*/result.json")]
    work_s = sum(r["cell_s"] for r in rows)
    # each cell's own config (configs/ also holds the seed group's config at replicate 0)
    configs = sorted(work / "sweep" / "configs" / f"{r['cell']}.json" for r in rows)
    print(
        f"sweep ({args.workers} workers): {t_sweep:8.1f} s  ({t_sweep / len(configs) * 1000:.0f} ms per cell; "
        f"cells' own work {work_s / len(rows) * 1000:.0f} ms each); load {load_sweep[0]:.2f} -> {load_sweep[1]:.2f}; "
        f"largest process {rss_sweep:.0f} MB"
    )
    if args.sweep_only:
        return
    loop_dir = work / "loop"
    rss_loop = 0.0
    load0 = os.getloadavg()[0]
    t0 = time.perf_counter()
    for cfg in configs:
        for cmd in (
            [studio, "synth", str(cfg), "-o", str(loop_dir), "-q", "--no-rrd"],
            [studio, "evaluate", str(loop_dir / cfg.stem), "--json"],
        ):
            proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL)
            _, status, usage = os.wait4(proc.pid, 0)
            proc.returncode = os.waitstatus_to_exitcode(status)
            if proc.returncode:
                raise SystemExit(f"{' '.join(cmd)}: exit {proc.returncode}")
            rss_loop = max(rss_loop, usage.ru_maxrss / 1024)
    t_loop = time.perf_counter() - t0
    load_loop = (load0, os.getloadavg()[0])
    print(
        f"CLI loop (sequential):  {t_loop:8.1f} s  ({t_loop / len(configs) * 1000:.0f} ms per cell); "
        f"load {load_loop[0]:.2f} -> {load_loop[1]:.2f}; largest process {rss_loop:.0f} MB"
    )
    print(
        f"speed-up: {t_loop / t_sweep:.2f}x; sweep overhead per cell beyond its work on {args.workers} workers: "
        f"{(t_sweep * args.workers - work_s) / len(rows) * 1000:.0f} ms"
    )


if __name__ == "__main__":
    main()
