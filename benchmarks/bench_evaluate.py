"""Benchmark `studio evaluate` on Multi10000x5 (50,005 poses): wall seconds and peak memory.

    python benchmarks/bench_evaluate.py [--dataset DIR] [--estimate PATH] [--repeat N]

Without ``--dataset`` the preset is synthesized into a temporary folder first (not timed). Each run
happens in a fresh interpreter so that start-up (imports) and evaluation are measured apart:

* ``start-up``: importing studio.evaluate, evo and scipy;
* ``evaluate``: ``studio.evaluate.evaluate(DATASET)``: reading the multi-g2o folder and scoring
  (the issue's budget: under 2 s);
* ``peak memory``: the process's peak resident set size, and the peak of Python/numpy allocations
  during ``evaluate`` (tracemalloc).
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
import json, resource, sys, time, tracemalloc
t0 = time.perf_counter()
import evo.core.metrics, evo.core.sync, evo.core.geometry, evo.core.trajectory, scipy.spatial.transform
from studio.evaluate import evaluate
t1 = time.perf_counter()
tracemalloc.start()
ev = evaluate(sys.argv[1], estimate=sys.argv[2] or None)
t2 = time.perf_counter()
_, traced = tracemalloc.get_traced_memory()
tracemalloc.stop()
print(json.dumps({"startup_s": t1 - t0, "evaluate_s": t2 - t1, "traced_peak_mb": traced / 2**20,
                  "max_rss_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024,
                  "poses": ev.overall.poses, "ape_mean": ev.overall.ape_translation_m.mean}))
"""

_CHILD_UNTRACED = _CHILD.replace("tracemalloc.start()", "").replace(
    "_, traced = tracemalloc.get_traced_memory()", "traced = 0").replace("tracemalloc.stop()", "")


def _run(dataset: str, estimate: str, traced: bool) -> dict:
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(filter(None, [str(REPO), os.environ.get("PYTHONPATH")])))
    out = subprocess.run([sys.executable, "-c", _CHILD if traced else _CHILD_UNTRACED, dataset, estimate],
                         check=True, capture_output=True, text=True, env=env)
    return json.loads(out.stdout)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--dataset", help="a multi-g2o folder (default: synthesize Multi10000x5)")
    parser.add_argument("--estimate", default="", help="an estimate to score (default: the initial estimate)")
    parser.add_argument("--repeat", type=int, default=3, help="timed runs; the fastest is reported")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        dataset = args.dataset
        if dataset is None:
            from studio.generator.presets import preset
            from studio.synth import synthesize

            dataset = str(synthesize(preset("multi10000x5"), tmp).dataset_dir)
        runs = [_run(dataset, args.estimate, traced=False) for _ in range(args.repeat)]
        best = min(runs, key=lambda r: r["evaluate_s"])
        mem = _run(dataset, args.estimate, traced=True)  # tracemalloc slows allocation: not timed
    print(f"dataset:      {dataset} ({best['poses']} poses, APE mean {best['ape_mean']:.6f} m)")
    print(f"start-up:     {best['startup_s']:.2f} s (imports)")
    print(f"evaluate:     {best['evaluate_s']:.2f} s wall (best of {len(runs)}: "
          f"{', '.join('%.2f' % r['evaluate_s'] for r in runs)})")
    print(f"peak memory:  {max(r['max_rss_mb'] for r in runs):.0f} MB resident (whole process), "
          f"{mem['traced_peak_mb']:.0f} MB allocated during evaluate")


if __name__ == "__main__":
    main()
