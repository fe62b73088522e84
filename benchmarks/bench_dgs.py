"""Time `studio solve --method dgs` (Distributed Gauss-Seidel) beside the centralized batch solve
(`studio solve`, GTSAM) on the paper's presets, whole processes, the multi-g2o folder as input (one
robot per agent).

    python benchmarks/bench_dgs.py [--presets multi3500x8 multi10000x5] [--rounds 100] [--plot PNG] [--out DIR]

Prints, per preset: the wall time and peak resident memory of each solve, chi2, the final APE
(translation mean, first-pose and se3 aligned, as `studio evaluate` scores it), DGS's rounds
(rotation and pose stage) and bytes sent, how far its final APE is from the batch optimum, then DGS's
APE after each round. ``--plot`` draws those curves (APE vs round, the batch optimum as a line) with
matplotlib.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
import time
from pathlib import Path

from timing import run_timed, work_folder  # noqa: E402  (benchmarks/timing.py, beside this script)

PRESETS = ["multi3500x8", "multi10000x5"]


def _ape(studio: str, dataset: Path, estimate: Path) -> dict[str, float]:
    out = {}
    for align in ("first-pose", "se3"):
        ev = subprocess.run(
            [studio, "evaluate", str(dataset), "--estimate", str(estimate), "--align", align, "--json"],
            check=True,
            capture_output=True,
            text=True,
        )
        out[align] = json.loads(ev.stdout)["all"]["ape_translation_m"]["mean"]
    return out


def _plot(path: Path, curves: dict[str, dict], batch: dict[str, dict[str, float]]) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, len(curves), figsize=(5.5 * len(curves), 4), squeeze=False, layout="tight")
    for ax, (name, curve) in zip(axes[0], curves.items()):
        for key, align, color in (("first_pose_mean_m", "first-pose", "C0"), ("se3_mean_m", "se3", "C1")):
            ax.plot(curve["round"], curve[key], "o-", ms=2.5, color=color, label=f"DGS, {align}")
            ax.axhline(batch[name][align], color=color, ls="--", lw=1, label=f"batch optimum, {align}")
        ax.set_yscale("log")
        ax.set_xlabel("round (0: dead reckoning; the rotation stage's rounds have no poses)")
        ax.set_ylabel("APE translation mean [m]")
        ax.set_title(f"{name}: Distributed Gauss-Seidel")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=7)
    fig.savefig(path, dpi=110)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--presets", nargs="*", default=PRESETS, help="presets to solve")
    ap.add_argument("--rounds", type=int, default=100, help="DGS rounds at most (default 100)")
    ap.add_argument("--plot", type=Path, default=None, help="write the APE-per-round curves to this PNG")
    ap.add_argument("--out", type=Path, default=None, help="work folder (default: a temporary folder)")
    args = ap.parse_args()
    studio = shutil.which("studio") or str(Path(sys.executable).parent / "studio")
    work = work_folder(args.out)
    print(
        f"# {time.strftime('%Y-%m-%d')}  {os.cpu_count()} cores  python {sys.version.split()[0]}  "
        f"load {os.getloadavg()[0]:.2f}  input multi-g2o folder"
    )
    print(
        f"{'dataset':13} {'method':6} {'wall s':>7} {'peak MiB':>9} {'chi2':>12} {'APE 1st-pose':>12} "
        f"{'APE se3':>8} {'rounds':>13} {'MB sent':>8}"
    )
    curves: dict[str, dict] = {}
    batch: dict[str, dict[str, float]] = {}
    for name in args.presets:
        subprocess.run([studio, "synth", name, "-o", str(work), "-q", "--no-rrd", "--force"], check=True)
        dataset = work / name
        results = {}
        for method in ("gtsam", "dgs"):
            out = work / f"{name}-{method}"
            cmd = [studio, "solve", str(dataset), "-o", str(out), "-m", method, "--force"]
            if method == "dgs":
                cmd += ["--iterations", str(args.rounds)]
            wall, rss = run_timed(cmd)
            info = json.loads((out / "solve.json").read_text())
            ape = _ape(studio, dataset, out / info["estimate"])
            results[method] = (info, ape)
            rounds, sent = "", ""
            if method == "dgs":
                n = info["notes"]
                rounds = f"{n['rounds']} ({n['rotation_rounds']}+{n['pose_rounds']})"
                sent = f"{n['bytes_total'] / 1e6:.1f}"
                curves[name] = info["ape_per_round"]
            print(
                f"{name:13} {method:6} {wall:7.2f} {rss:9.0f} {info['chi2_final']:12.1f} {ape['first-pose']:12.4f} "
                f"{ape['se3']:8.4f} {rounds:>13} {sent:>8}",
                flush=True,
            )
        batch[name] = results["gtsam"][1]
        dgs = results["dgs"][1]
        print(
            f"{name:13} dgs / batch APE: first-pose {dgs['first-pose'] / batch[name]['first-pose']:.2f}x, "
            f"se3 {dgs['se3'] / batch[name]['se3']:.2f}x (within 10 %: "
            f"{'yes' if max(dgs[a] / batch[name][a] for a in dgs) <= 1.1 else 'no'})"
        )
        curve = curves[name]
        print(f"{name:13} APE per round (round: first-pose / se3 mean [m]):")
        cells = [
            f"{k}: {fp:.3f}/{s3:.3f}"
            for k, fp, s3 in zip(curve["round"], curve["first_pose_mean_m"], curve["se3_mean_m"])
        ]
        for i in range(0, len(cells), 6):
            print("    " + "   ".join(cells[i : i + 6]))
    if args.plot is not None:
        _plot(args.plot, curves, batch)
        print(f"plot: {args.plot}")


if __name__ == "__main__":
    main()
