"""`studio convert` on real-shaped inputs: five EuRoC machine-hall sequences as five agents, a
KITTI poses file of 4,500 poses split into three robots, and an MR.CLAM dataset folder (five robots,
ground truth at 100 Hz, odometry at about 67 Hz, robot sightings) with its real odometry.

    python benchmarks/bench_convert_real.py [--euroc-rows 30000] [--kitti-poses 4500] [--mrclam-seconds 1500]
        [--repeat 3] [--out DIR]

The inputs are written by the script in the datasets' exact formats (EuRoC's 17-column data.csv at
200 Hz with nanosecond stamps and w x y z quaternions; KITTI's 12-number pose lines with times.txt),
then converted as whole processes. Prints the median wall time and the peak resident memory.
"""

from __future__ import annotations

import argparse
import os
import shutil
import statistics
import sys
import time
from pathlib import Path

import numpy as np
from timing import run_timed, work_folder  # noqa: E402  (benchmarks/timing.py, beside this script)


def write_euroc(root: Path, rows: int) -> list[Path]:
    seqs = []
    for k in range(5):
        seq = root / f"MH_0{k + 1}_easy"
        folder = seq / "mav0" / "state_groundtruth_estimate0"
        folder.mkdir(parents=True)
        t = 1_403_636_579_758_555_392 + np.arange(rows, dtype=np.int64) * 5_000_000
        a = 0.3 * k + np.linspace(0, 6 * np.pi, rows)
        p = np.column_stack([4 * np.cos(a) + k, 3 * np.sin(a), 1 + 0.3 * np.sin(2 * a)])
        yaw = a + np.pi / 2
        q = np.column_stack([np.cos(yaw / 2), np.zeros(rows), np.zeros(rows), np.sin(yaw / 2)])
        cols = np.column_stack([p, q, np.zeros((rows, 9))])
        body = "\n".join(f"{s}," + ",".join(f"{v:.9f}" for v in row) for s, row in zip(t.tolist(), cols.tolist()))
        (folder / "data.csv").write_text("#timestamp, p_RS_R_x [m], ...\n" + body + "\n")
        seqs.append(seq)
    return seqs


def write_kitti(root: Path, n: int) -> Path:
    (root / "poses").mkdir(parents=True)
    yaw = np.cumsum(np.sin(np.arange(n) / 150.0) * 0.01)
    pos = np.column_stack([np.cumsum(np.sin(yaw)), np.zeros(n), np.cumsum(np.cos(yaw))]) * 1.1
    lines = []
    for i in range(n):
        c, s = np.cos(yaw[i]), np.sin(yaw[i])
        m = np.array([[c, 0, s, pos[i, 0]], [0, 1, 0, 0], [-s, 0, c, pos[i, 2]]])
        lines.append(" ".join(f"{v:.9e}" for v in m.ravel()))
    (root / "poses" / "00.txt").write_text("\n".join(lines) + "\n")
    (root / "poses" / "times.txt").write_text("\n".join(f"{v:.6e}" for v in np.arange(n) * 0.1036) + "\n")
    return root / "poses" / "00.txt"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--euroc-rows", type=int, default=30000, help="ground-truth rows per EuRoC sequence")
    ap.add_argument("--kitti-poses", type=int, default=4500, help="poses of the KITTI file")
    ap.add_argument("--mrclam-seconds", type=float, default=1500.0, help="length of the MR.CLAM run (0: none)")
    ap.add_argument("--repeat", type=int, default=3, help="runs per job")
    ap.add_argument("--out", type=Path, default=None, help="work folder (default: a temporary folder)")
    args = ap.parse_args()
    studio = shutil.which("studio") or str(Path(sys.executable).parent / "studio")
    work = work_folder(args.out)
    seqs = write_euroc(work / "euroc", args.euroc_rows)
    kitti = write_kitti(work / "kitti", args.kitti_poses)
    jobs = {
        f"euroc 5 x {args.euroc_rows} rows": [studio, "convert", "euroc", *map(str, seqs)],
        f"kitti {args.kitti_poses} poses --split 3": [
            studio,
            "convert",
            "kitti",
            str(kitti),
            "--split",
            "3",
            "--overlap",
            "10",
        ],
    }
    if args.mrclam_seconds > 0:
        sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # the tests' MR.CLAM-layout writer
        from tests.converters.mrclam_files import write_mrclam_dataset

        mrclam = write_mrclam_dataset(work / "MRCLAM_Dataset1", seconds=args.mrclam_seconds)
        jobs[f"mrclam {args.mrclam_seconds:g} s --odometry real"] = [
            studio,
            "convert",
            "mrclam",
            str(mrclam),
            "--planar",
            "--odometry",
            "real",
        ]
    print(f"# {time.strftime('%Y-%m-%d')}  {os.cpu_count()} cores  load {os.getloadavg()[0]:.2f}")
    for label, cmd in jobs.items():
        walls, peak = [], 0.0
        for k in range(args.repeat):
            wall, rss = run_timed([*cmd, "-o", str(work / f"out{k}"), "-q", "--force"])
            walls.append(wall)
            peak = max(peak, rss)
        print(f"{label:32} median {statistics.median(walls):6.2f} s  best {min(walls):6.2f} s  peak {peak:5.0f} MiB")


if __name__ == "__main__":
    main()
