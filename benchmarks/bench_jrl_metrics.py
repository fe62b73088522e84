"""Benchmark `studio evaluate DATASET --estimate FILE.jrr` (jrl's metrics into a .jrm): wall and CPU
seconds and peak memory.

    python benchmarks/bench_jrl_metrics.py [--dataset DIR_OR_JRL] [--jrr FILE.jrr] [--repeat N]

Without ``--dataset`` Multi10000x5 (50,005 poses) is synthesized into a temporary folder, and
without ``--jrr`` a results file is made from its initial estimate (not timed): every robot holds
its own poses and, like a distributed back-end, a copy of the other end of each inter-robot
closure it measured, moved by 0.1 m and 0.01 rad so that SVE and the mean residual's Cartesian
products have work to do. Each run is a fresh interpreter:

* ``start-up``: importing the command's modules;
* ``metrics``: ``studio.jrl_evaluate.evaluate_jrr``: reading the dataset (a multi-g2o folder is
  seen through the studio's JRL export), the .jrr, scoring, writing the .jrm;
* ``peak memory``: the process's peak resident set size and how much of it the metrics added.
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
from studio.jrl_evaluate import evaluate_jrr
import studio.io.jrl, studio.io.multig2o, studio.io.jrr, studio.io.jrm
t1, c1 = time.perf_counter(), time.process_time()
with open("/proc/self/statm") as f:
    rss_before_mb = int(f.read().split()[1]) * os.sysconf("SC_PAGE_SIZE") / 2**20
res = evaluate_jrr(sys.argv[1], sys.argv[2], jrm=sys.argv[3], force=True)
t2, c2 = time.perf_counter(), time.process_time()
max_rss_mb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
s = res.summary
print(json.dumps({"startup_s": t1 - t0, "metrics_s": t2 - t1, "cpu_s": c2 - c1, "rss_before_mb": rss_before_mb,
                  "max_rss_mb": max_rss_mb, "total_ate": s.total_ate, "sve": s.sve,
                  "mean_residual": s.mean_residual}))
"""


def _run(dataset: str, jrr: str, jrm: str) -> dict:
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(filter(None, [str(REPO), os.environ.get("PYTHONPATH")])))
    out = subprocess.run(
        [sys.executable, "-c", _CHILD, dataset, jrr, jrm], check=True, capture_output=True, text=True, env=env
    )
    return json.loads(out.stdout)


def make_jrr(dataset: Path, path: Path) -> None:
    """A .jrr of ``dataset``'s initial estimate with perturbed copies of the shared poses."""
    import numpy as np

    from studio.core.geometry import quat_from_rotvec, quat_mul
    from studio.io.jrr import write_jrr
    from studio.io.multig2o import read_multi_g2o
    from studio.io.symbol_g2o import robot_prefix
    from studio.jrl_evaluate import graph_results

    graph = read_multi_g2o(dataset).to_se3()
    robots = [robot_prefix(k) for k in range(len(graph.agents))]
    own = [np.asarray(a.initial) for a in graph.agents]
    inter = graph.inter
    shared = []
    for k in range(len(robots)):
        mine = inter.from_agent == k
        agents, index = inter.to_agent[mine], inter.to_index[mine]
        keys, first = np.unique((np.int64(1) << 56) * np.array([ord(robots[a]) for a in agents]) + index, True)
        poses = np.array([own[a][i] for a, i in zip(agents[first], index[first])]).reshape(-1, 7)
        poses[:, 0:3] += 0.1 / np.sqrt(3)
        turn = quat_from_rotvec(np.tile([0.0, 0.0, 0.01], (len(poses), 1)))
        poses[:, 3:7] = quat_mul(poses[:, 3:7], turn)
        shared.append((keys.astype(np.int64), poses))
    write_jrr(
        path, graph_results(graph.kind, robots, own, dataset_name=dataset.name, method_name="bench", shared=shared)
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--dataset", help="a multi-g2o folder or JRL file (default: synthesize Multi10000x5)")
    parser.add_argument("--jrr", help="the results to score (default: made from the dataset, see above)")
    parser.add_argument("--repeat", type=int, default=3, help="timed runs; the fastest is reported")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp_dir:
        tmp = Path(tmp_dir)
        dataset = args.dataset
        if dataset is None:
            from studio.generator.presets import preset
            from studio.synth import synthesize

            dataset = str(synthesize(preset("multi10000x5"), tmp).dataset_dir)
        jrr = args.jrr
        if jrr is None:
            jrr = str(tmp / "bench.jrr")
            make_jrr(Path(dataset), Path(jrr))
        runs = [_run(dataset, jrr, str(tmp / "bench.jrm")) for _ in range(args.repeat)]
    best = min(runs, key=lambda r: r["metrics_s"])
    print(f"dataset:      {dataset}; results {jrr}")
    print(f"metrics:      total ATE {best['total_ate']}, SVE {best['sve']}, mean residual {best['mean_residual']:.9g}")
    print(f"start-up:     {best['startup_s']:.2f} s (imports)")
    print(
        f"evaluate:     {best['metrics_s']:.2f} s wall, {best['cpu_s']:.2f} s CPU (best of {len(runs)}: "
        f"{', '.join(format(r['metrics_s'], '.2f') for r in runs)} s wall)"
    )
    peak = max(runs, key=lambda r: r["max_rss_mb"])
    print(
        f"peak memory:  {peak['max_rss_mb']:.0f} MiB resident (whole process), of which "
        f"{peak['max_rss_mb'] - peak['rss_before_mb']:.0f} MiB added by the metrics"
    )


if __name__ == "__main__":
    main()
