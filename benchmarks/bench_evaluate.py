"""Benchmark `studio evaluate` on Multi10000x5 (50,005 poses): wall seconds and peak memory.

    python benchmarks/bench_evaluate.py [--dataset DIR] [--estimate PATH] [--repeat N]

Without ``--dataset`` the preset is synthesized into a temporary folder first (not timed). Each run
happens in a fresh interpreter so that start-up (imports) and evaluation are measured apart:

* ``start-up``: importing studio.evaluate, evo and scipy;
* ``evaluate``: ``studio.evaluate.evaluate(DATASET)``: reading the multi-g2o folder and scoring
  (the issue's budget: under 2 s);
* ``peak memory``: the process's peak resident set size, and how much of it ``evaluate`` added
  (peak resident minus resident after the imports, both measured in the same process; allocations
  that are never touched, e.g. ``np.empty``, are not resident and so are not counted).
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(REPO))

_CHILD = r"""
import json, os, resource, sys, time
t0 = time.perf_counter()
import evo.core.metrics, evo.core.sync, evo.core.geometry, evo.core.trajectory, scipy.spatial.transform
from studio.evaluate import evaluate
t1 = time.perf_counter()
with open("/proc/self/statm") as f:
    rss_before_mb = int(f.read().split()[1]) * os.sysconf("SC_PAGE_SIZE") / 2**20
ev = evaluate(sys.argv[1], estimate=sys.argv[2] or None)
t2 = time.perf_counter()
max_rss_mb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
print(json.dumps({"startup_s": t1 - t0, "evaluate_s": t2 - t1, "rss_before_mb": rss_before_mb,
                  "max_rss_mb": max_rss_mb,
                  "poses": ev.overall.poses, "ape_mean": ev.overall.ape_translation_m.mean}))
"""


def _run(dataset: str, estimate: str) -> dict:
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(filter(None, [str(REPO), os.environ.get("PYTHONPATH")])))
    out = subprocess.run(
        [sys.executable, "-c", _CHILD, dataset, estimate], check=True, capture_output=True, text=True, env=env
    )
    return json.loads(out.stdout)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--dataset", help="a multi-g2o folder (default: synthesize Multi10000x5)")
    parser.add_argument("--estimate", default="", help="an estimate to score (default: the initial estimate)")
    parser.add_argument("--repeat", type=int, default=3, help="timed runs; the fastest is reported")
    parser.add_argument(
        "--out",
        type=Path,
        default=None,
        help="folder for the synthesized dataset (default: a temporary folder, removed after)",
    )
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp_dir:
        tmp = args.out or Path(tmp_dir)
        dataset = args.dataset
        if dataset is None:
            from studio.generator.presets import preset
            from studio.synth import synthesize

            dataset = str(synthesize(preset("multi10000x5"), tmp).dataset_dir)
        runs = [_run(dataset, args.estimate) for _ in range(args.repeat)]
        best = min(runs, key=lambda r: r["evaluate_s"])
    print(f"dataset:      {dataset} ({best['poses']} poses, APE mean {best['ape_mean']:.6f} m)")
    print(f"start-up:     {best['startup_s']:.2f} s (imports)")
    print(
        f"evaluate:     {best['evaluate_s']:.2f} s wall (best of {len(runs)}: "
        f"{', '.join(format(r['evaluate_s'], '.2f') for r in runs)})"
    )
    peak = max(runs, key=lambda r: r["max_rss_mb"])
    print(
        f"peak memory:  {peak['max_rss_mb']:.0f} MiB resident (whole process), of which "
        f"{peak['max_rss_mb'] - peak['rss_before_mb']:.0f} MiB added by evaluate "
        f"({peak['rss_before_mb']:.0f} MiB after the imports)"
    )


if __name__ == "__main__":
    main()
