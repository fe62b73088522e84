"""Time `studio solve` end to end (whole processes: read, initial guess, iterations, write) on the
paper's presets, the default method beside the paper's g2o setup (spanning tree + Gauss-Newton 10).

    python benchmarks/bench_solve.py [--repeat 3] [--presets multi3500x8] [--input single|multi] [--out DIR]

Prints, per preset and method, the median and best wall time, the peak resident memory, chi2 and the
APE under first-pose and se3 alignment (from `studio evaluate`), and the speed-up of the default
method over g2o.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import statistics
import subprocess
import sys
import time
from pathlib import Path

from timing import run_timed, work_folder  # noqa: E402  (benchmarks/timing.py, beside this script)

PRESETS = ["multi3500x8", "multi10000x5"]
METHODS = ["gtsam", "g2o"]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--repeat", type=int, default=3, help="runs per method (default 3)")
    ap.add_argument("--presets", nargs="*", default=PRESETS, help="presets to solve")
    ap.add_argument("--methods", nargs="*", default=METHODS, help="methods to run")
    ap.add_argument(
        "--input",
        choices=["single", "multi"],
        default="single",
        help="solve the single g2o (as the paper) or the multi-g2o folder",
    )
    ap.add_argument("--out", type=Path, default=None, help="work folder (default: a temporary folder)")
    args = ap.parse_args()
    studio = shutil.which("studio") or str(Path(sys.executable).parent / "studio")
    work = work_folder(args.out)
    print(
        f"# {time.strftime('%Y-%m-%d')}  {os.cpu_count()} cores  python {sys.version.split()[0]}  "
        f"load {os.getloadavg()[0]:.2f}  input {args.input}"
    )
    print(
        f"{'dataset':13} {'method':7} {'median s':>9} {'best s':>7} {'peak MiB':>9} {'chi2':>12} "
        f"{'APE 1st-pose':>12} {'APE se3':>8}"
    )
    for name in args.presets:
        subprocess.run([studio, "synth", name, "-o", str(work), "-q", "--no-rrd", "--force"], check=True)
        dataset = work / name
        source = work / f"{name}_singleg2o" / f"{name}.g2o" if args.input == "single" else dataset
        medians = {}
        for method in args.methods:
            walls, peak = [], 0.0
            out = work / f"{name}-{method}"
            for _ in range(args.repeat):
                wall, rss = run_timed([studio, "solve", str(source), "-o", str(out), "-m", method, "--force"])
                walls.append(wall)
                peak = max(peak, rss)
            info = json.loads((out / "solve.json").read_text())
            estimate = out / info["estimate"]
            ape = {}
            for align in ("first-pose", "se3"):
                ev = subprocess.run(
                    [studio, "evaluate", str(dataset), "--estimate", str(estimate), "--align", align, "--json"],
                    check=True,
                    capture_output=True,
                    text=True,
                )
                ape[align] = json.loads(ev.stdout)["all"]["ape_translation_m"]["mean"]
            medians[method] = statistics.median(walls)
            print(
                f"{name:13} {method:7} {medians[method]:9.2f} {min(walls):7.2f} {peak:9.0f} "
                f"{info['chi2_final']:12.2f} {ape['first-pose']:12.6f} {ape['se3']:8.5f}"
            )
        if "gtsam" in medians and "g2o" in medians:
            print(f"{name:13} speed-up of gtsam over g2o: {medians['g2o'] / medians['gtsam']:.2f}x (median wall)")


if __name__ == "__main__":
    main()
