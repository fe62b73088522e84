"""Export and import of a paper-size dataset in each distributed back-end's format, beside writing its
multi-g2o, in one run: wall seconds and peak memory of each command.

    python benchmarks/bench_interop.py [--preset multi10000x5] [--repeat 3] [--out DIR]

The dataset is made once (``studio synth PRESET --no-rrd``). Then, each as its own process, ``--repeat``
times (the median is printed):

* ``multi-g2o``: read the dataset and write it again as a multi-g2o folder (``read_multi_g2o`` +
  ``write_multi_g2o(precision="full")``), the yardstick;
* ``export F``: ``studio export DATASET --format F -o ...`` (read the dataset, write format F);
* ``import F``: ``studio convert F EXPORT -o ... --no-rrd`` (read format F, write a multi-g2o folder).

Each row shows its ratio to the yardstick. The machine's load (``os.getloadavg``) is printed before
the runs: the figures of a busy machine are slower.
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from timing import run_timed, work_folder  # noqa: E402  (benchmarks/timing.py, beside this script)

FORMATS = ("jrl", "dpgo", "symbols")
_BASELINE = (
    "import sys\n"
    "from pathlib import Path\n"
    "from studio.io.multig2o import read_multi_g2o, write_multi_g2o\n"
    "g = read_multi_g2o(sys.argv[1])\n"
    "import shutil; shutil.rmtree(sys.argv[2], ignore_errors=True); Path(sys.argv[2]).mkdir()\n"
    "write_multi_g2o(g, sys.argv[2], precision='full')\n"
)


def _studio(*args: str) -> list[str]:
    return [sys.executable, "-m", "studio.cli", *args]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--preset", default="multi10000x5")
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--out", type=Path, default=None, help="Work folder (default: a temporary one).")
    args = parser.parse_args()
    os.environ.setdefault("CI", "true")
    os.environ["RERUN_ANALYTICS"] = "0"
    work = work_folder(args.out)
    run_timed(_studio("synth", args.preset, "-o", str(work), "--no-rrd", "-q", "--force"))
    dataset = work / args.preset
    print(f"{args.preset}: load average {' '.join(f'{x:.2f}' for x in os.getloadavg())} (1, 5, 15 min)")
    rows: list[tuple[str, float, float]] = []

    def timed(label: str, make_cmd) -> None:
        walls, peaks = [], []
        for k in range(args.repeat):
            wall, peak = run_timed(make_cmd(k))
            walls.append(wall)
            peaks.append(peak)
        rows.append((label, statistics.median(walls), max(peaks)))

    timed("multi-g2o", lambda k: [sys.executable, "-c", _BASELINE, str(dataset), str(work / f"copy{k}")])
    for fmt in FORMATS:
        target = work / (f"{args.preset}.jrl" if fmt == "jrl" else f"{args.preset}_{fmt}")
        timed(
            f"export {fmt}",
            lambda k, f=fmt, t=target: _studio("export", str(dataset), "-f", f, "-o", str(t), "--force", "-q"),
        )
        timed(
            f"import {fmt}",
            lambda k, f=fmt, t=target: _studio(
                "convert", f, str(t), "-o", str(work / f"back_{f}"), "--no-rrd", "-q", "--force"
            ),
        )
    base = rows[0][1]
    print(f"{'step':<16} {'wall [s]':>9} {'peak [MiB]':>11} {'x multi-g2o':>12}")
    for label, wall, peak in rows:
        print(f"{label:<16} {wall:9.2f} {peak:11.0f} {wall / base:12.2f}")
    print(f"load average after: {' '.join(f'{x:.2f}' for x in os.getloadavg())}")


if __name__ == "__main__":
    main()
