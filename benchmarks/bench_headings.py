"""Derived headings on real paths: each method's correlation with the real heading, per path and rate.

    python benchmarks/bench_headings.py DIR [--rates native 2 1] [--markdown]

DIR holds real ground-robot paths with orientation (the layout of the real-data test,
``tests/converters/test_derived_headings.py::test_real_ground_robot_paths``: ``MRCLAM_Dataset*/``
folders, KITTI ``poses/NN.txt`` with ``sequences/NN/times.txt``, ``*.tum`` files). Each path is taken
as recorded and subsampled to each rate; the headings each method derives from its positions alone
are compared with its own orientation: the correlation of the yaw increments at keyframes every
0.5 s (every pose where sparser). Prints, per path and rate, ``chord`` (2 m), ``smoothed``,
``turns``, ``auto`` and what ``auto`` chose, and flags a row where ``auto`` is more than 0.02 below
the best fixed method or below ``chord``.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from studio.converters.heading_choice import choose_heading_method  # noqa: E402
from tests.converters.test_derived_headings import (  # noqa: E402
    _positions_only,
    method_correlation,
    real_paths,
    subsampled,
)

METHODS = ("chord", "smoothed", "turns", "auto")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("root", type=Path)
    ap.add_argument("--rates", nargs="+", default=["native", "2", "1"], help="native or a rate in Hz")
    ap.add_argument("--markdown", action="store_true", help="a Markdown table")
    args = ap.parse_args()
    rates = [None if r == "native" else float(r) for r in args.rates]
    head = ["path", "rate", *METHODS, "auto chose", ""]
    print("| " + " | ".join(head) + " |" if args.markdown else "  ".join(head))
    if args.markdown:
        print("|---|---|" + "---:|" * len(METHODS) + "---|---|")
    failed = 0
    for name, traj in real_paths(args.root):
        for rate in rates:
            t = subsampled(traj, rate)
            got = {m: method_correlation(t, m) for m in METHODS}
            choice = choose_heading_method(_positions_only(t.stamps_ns, t.positions_xyz))
            chose = choice.method
            if chose == "chord":
                chose += f" {choice.window_m:.2g} m, +-{choice.smooth_s:.2g} s"
            ok = got["auto"] >= max(got[m] for m in METHODS[:3]) - 0.02 and got["auto"] >= got["chord"]
            failed += not ok
            cells = [name, f"{choice.rate_hz:.3g} Hz", *(f"{got[m]:.3f}" for m in METHODS), chose, "" if ok else "FAIL"]
            print("| " + " | ".join(cells) + " |" if args.markdown else "  ".join(cells), flush=True)
    print(f"{failed} rows where auto is more than 0.02 below the best fixed method or below chord")


if __name__ == "__main__":
    main()
