"""Replay's goals: every back-end on Multi3500x8 and Multi10000x5 under ``always``, ``range:20`` and
a rendezvous file, ``--every 50``, each in under 60 s and 1 GB (one ``studio replay`` process per
back-end), optionally side by side with another installation of the studio.

    python benchmarks/bench_replay_goals.py [--presets multi3500x8 multi10000x5]
        [--comms always range:20 rendezvous] [--backends centralized independent swarm dgs]
        [--anchor /path/to/other/venv/bin/studio] [--out DIR]

Prints per run: wall time, CPU time (user + system), peak resident memory of the whole process and
the final team APE (first-pose and se3) from its summary.csv. ``rendezvous`` is the file of
docs/replay.md's comparison (robot *k* in a window of 100 s every 500 s from 10*k* s), written
beside the datasets. With ``--anchor``, each run is made with both installations one after the
other (the anchor first), so that a change of the machine's load reaches both alike; the APE
columns then show how far the two results lie apart.
"""

from __future__ import annotations

import argparse
import csv
import os
import shutil
import subprocess
import sys
import time
from pathlib import Path

from timing import run_measured, work_folder  # noqa: E402  (benchmarks/timing.py, beside this script)

GOAL_SECONDS = 60.0
GOAL_MIB = 1024.0


def rendezvous_lines(robots: int, end_s: int) -> list[str]:
    """Robot k in a window of 100 s every 500 s from 10 k s (Swarm-SLAM's format)."""
    lines = []
    for k in range(robots):
        windows: list[int] = []
        for s in range(10 * k, end_s, 500):
            windows += [s, min(s + 100, end_s)]
        lines.append(",".join(map(str, [k, *windows])))
    return lines


def _dataset(studio: str, preset: str, work: Path) -> tuple[Path, Path]:
    subprocess.run([studio, "synth", preset, "-o", str(work), "-q", "--no-rrd", "--force"], check=True)
    dataset = work / preset
    agents = sorted(p for p in dataset.iterdir() if p.is_dir())
    steps = int(preset.removeprefix("multi").split("x")[0])
    rdv = work / f"rdv-{preset}.txt"
    rdv.write_text("\n".join(rendezvous_lines(len(agents), steps)) + "\n", encoding="ascii")
    return dataset, rdv


def _ape(folder: Path, backend: str) -> tuple[float, float]:
    with open(folder / "summary.csv", encoding="utf-8") as f:
        row = next(r for r in csv.DictReader(f) if r["backend"] == backend)
    return float(row["ape_first_pose_m"]), float(row["ape_se3_m"])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--presets", nargs="*", default=["multi3500x8", "multi10000x5"])
    ap.add_argument("--comms", nargs="*", default=["always", "range:20", "rendezvous"])
    ap.add_argument("--backends", nargs="*", default=["centralized", "independent", "swarm", "dgs"])
    ap.add_argument("--every", type=int, default=50)
    ap.add_argument("--anchor", default=None, help="another installation's `studio` to run beside this one")
    ap.add_argument("--out", type=Path, default=None, help="work folder (default: a temporary folder)")
    args = ap.parse_args()
    studio = shutil.which("studio") or str(Path(sys.executable).parent / "studio")
    installs = [("anchor", args.anchor), ("this", studio)] if args.anchor else [("this", studio)]
    work = work_folder(args.out)
    print(f"# {time.strftime('%Y-%m-%d %H:%M')}  {os.cpu_count()} cores  load {os.getloadavg()[0]:.2f}", flush=True)
    print(
        f"{'run':44} {'studio':>6} {'wall s':>7} {'CPU s':>7} {'peak MiB':>8} {'APE 1st-pose':>12} {'APE se3':>9}  goal"
    )
    for preset in args.presets:
        dataset, rdv = _dataset(studio, preset, work)
        for comms in args.comms:
            model = f"rendezvous:{rdv}" if comms == "rendezvous" else comms
            for backend in args.backends:
                for name, program in installs:
                    out = work / f"{preset}-{comms.replace(':', '_')}-{backend}-{name}"
                    cmd = [program, "replay", str(dataset), "--comms", model, "-b", backend]
                    wall, cpu, peak = run_measured([*cmd, "--every", str(args.every), "-o", str(out), "--force"])
                    fp, se3 = _ape(out, backend)
                    met = "met" if wall < GOAL_SECONDS and peak < GOAL_MIB else "MISSED"
                    label = f"{preset} {comms} {backend}"
                    print(
                        f"{label:44} {name:>6} {wall:7.1f} {cpu:7.1f} {peak:8.0f} {fp:12.6f} {se3:9.6f}  {met}",
                        flush=True,
                    )


if __name__ == "__main__":
    main()
