"""Time `studio replay` end to end (whole processes) on a paper preset, each back-end under each
communication model, beside the batch optimum of `studio solve` and a plain per-step ISAM2 loop.

    python benchmarks/bench_replay.py [--preset multi3500x8] [--comms always range:5 ...]
        [--backends centralized independent swarm] [--every 50] [--loop-steps 500] [--variants N]
        [--rrd] [--out DIR]

Prints per run: wall time, CPU time (user + system) and peak resident memory of the whole `studio
replay` process, the final team APE (first-pose and se3) and chi2 from its summary.csv, the load
average when it ended, with `--rrd` the size of its recording, and the batch optimum's figures. On a
shared machine the wall time is the CPU time stretched by the other sessions' load (GTSAM's wheel
runs single-threaded): the CPU time is what an idle machine's wall time would be, near enough.
`--variants N` adds the first N of these centralized runs, which show what the incremental choices
cost: no final Gauss-Newton polish (`--no-polish`), relinearization checked every update
(`--relinearize-skip 1`).

The plain loop (one ISAM2 update per step, every factor at the step both its poses exist, GTSAM's
default parameters, a prior on each robot's first pose) is run for its first `--loop-steps` steps
only, in this process: its cost grows superlinearly as inter-agent closures tie the robots together,
so the figure is a lower bound of the whole loop, not an extrapolation (issue 24 measured the whole
loop on Multi3500x8: step 3000 of 3500 after 9.4 minutes, not finished after 15).
"""

from __future__ import annotations

import argparse
import csv
import json
import os
import shutil
import subprocess
import sys
import time
from pathlib import Path

from timing import run_measured, work_folder  # noqa: E402  (benchmarks/timing.py, beside this script)


def _summary(folder: Path) -> dict[str, dict[str, str]]:
    with open(folder / "summary.csv", encoding="utf-8") as f:
        return {row["backend"]: row for row in csv.DictReader(f)}


def _plain_loop(dataset: Path, steps: int) -> tuple[float, float, int]:
    import numpy as np

    from studio.core.timing import measurement_times
    from studio.solve import load_problem
    from studio.solvers.incremental import IncrementalSolver, IsamSettings

    loaded = load_problem(dataset)
    graph = loaded.graph
    assert graph is not None
    p = loaded.problem
    times = measurement_times(graph)
    sizes = [a.num_poses for a in graph.agents]
    agent = np.repeat(np.arange(len(sizes)), sizes)
    vertex_ns = np.concatenate(times.pose_ns)
    parts = []
    for k in range(len(sizes)):
        parts += [times.odometry_ns[k], times.loop_closure_ns[k]]
    edge_ns = np.concatenate(parts + [times.inter_ns])
    # the replay's gauge: a tight prior on the first robot's first pose, loose ones on the others'
    solver = IncrementalSolver(p, agent, IsamSettings(polish=False))
    stamps = np.unique(vertex_ns)[:steps]
    t0, c0 = time.perf_counter(), time.process_time()
    for t in stamps.tolist():
        v = np.flatnonzero((vertex_ns <= t) & ~solver.vertices)
        e = np.flatnonzero((edge_ns <= t) & ~solver.edges)
        solver.add(v, e)
    solver.solve()
    return time.perf_counter() - t0, time.process_time() - c0, len(stamps)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--preset", default="multi3500x8")
    ap.add_argument("--comms", nargs="*", default=["always", "never", "range:5", "range:20"])
    ap.add_argument("--backends", nargs="*", default=["centralized", "independent", "swarm"])
    ap.add_argument("--every", type=int, default=50, help="ticks between checkpoints (default 50)")
    ap.add_argument("--loop-steps", type=int, default=500, help="steps of the plain per-step loop (0: skip)")
    ap.add_argument("--variants", type=int, default=0, help="centralized variants: 1 no polish, 2 also skip 1")
    ap.add_argument("--rrd", action="store_true", help="each replay writes a recording too (its size printed)")
    ap.add_argument("--out", type=Path, default=None, help="work folder (default: a temporary folder)")
    args = ap.parse_args()
    studio = shutil.which("studio") or str(Path(sys.executable).parent / "studio")
    work = work_folder(args.out)
    print(f"# {time.strftime('%Y-%m-%d %H:%M')}  {os.cpu_count()} cores  load {os.getloadavg()[0]:.2f}", flush=True)
    subprocess.run([studio, "synth", args.preset, "-o", str(work), "-q", "--no-rrd", "--force"], check=True)
    dataset = work / args.preset
    wall, cpu, peak = run_measured([studio, "solve", str(dataset), "-o", str(work / "solved"), "--force"])
    chi2 = json.loads((work / "solved" / "solve.json").read_text())["chi2_final"]
    from studio.evaluate import evaluate

    est = work / "solved" / "estimate"
    fp = evaluate(dataset, estimate=est, align="first-pose").overall.ape_translation_m.mean
    se3 = evaluate(dataset, estimate=est, align="se3").overall.ape_translation_m.mean
    print(
        f"{'run':44} {'wall s':>7} {'CPU s':>7} {'peak MiB':>8} {'APE 1st-pose':>12} {'APE se3':>8} {'chi2':>12}"
        f"  load  {'rrd MB' if args.rrd else ''}"
    )
    print(
        f"{'batch optimum (studio solve)':44} {wall:7.1f} {cpu:7.1f} {peak:8.0f} {fp:12.6f} {se3:8.6f} {chi2:12.6g}"
        f"  {os.getloadavg()[0]:.2f}",
        flush=True,
    )
    runs = [(c, b, []) for c in args.comms for b in args.backends]
    variants = [("always", "centralized", ["--no-polish"]), ("always", "centralized", ["--relinearize-skip", "1"])]
    runs += variants[: args.variants]
    for comms, backend, extra in runs:
        out = work / f"replay-{comms.replace(':', '_')}-{backend}-{len(extra)}{''.join(extra)}"
        cmd = [studio, "replay", str(dataset), "--comms", comms, "-b", backend, "--every", str(args.every)]
        rrd = out.with_suffix(".rrd")
        wall, cpu, peak = run_measured(
            [*cmd, *extra, "-o", str(out), "--force"] + (["--rrd", str(rrd)] if args.rrd else [])
        )
        row = _summary(out)[backend]
        label = f"{backend} {comms} {' '.join(extra)}".strip()
        size = f"  {rrd.stat().st_size / 1e6:.1f}" if args.rrd else ""
        print(
            f"{label:44} {wall:7.1f} {cpu:7.1f} {peak:8.0f} {float(row['ape_first_pose_m']):12.6f} "
            f"{float(row['ape_se3_m']):8.6f} {float(row['chi2']):12.6g}  {os.getloadavg()[0]:.2f}{size}",
            flush=True,
        )
    if args.loop_steps:
        seconds, cpu, steps = _plain_loop(dataset, args.loop_steps)
        print(
            f"plain per-step ISAM2 loop: first {steps} steps in {seconds:.1f} s wall, {cpu:.1f} s CPU "
            f"(a lower bound of the whole loop; load {os.getloadavg()[0]:.2f})",
            flush=True,
        )


if __name__ == "__main__":
    main()
