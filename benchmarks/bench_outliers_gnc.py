"""Do planted outliers get rejected? GNC (`studio solve --method gnc`) on a small synthetic set.

    python benchmarks/bench_outliers_gnc.py [--agents 3] [--steps 300] [--fraction 0.05] [--walk kollagen|grid3d]

Generates Multi3500x8's parameters with fewer agents and steps and a `studio` block planting the
given fraction of intra- and inter-agent outliers (half random, half perceptual aliasing), solves it
with GNC, and prints the precision and recall of the rejected loop closures against `outliers.txt`,
per kind, with the wall time and peak memory.
"""

from __future__ import annotations

import argparse
import resource
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from studio.generator.presets import preset  # noqa: E402
from studio.io.synth_config import parse_synth_config, synth_config_to_json  # noqa: E402


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--agents", type=int, default=3)
    ap.add_argument("--steps", type=int, default=300)
    ap.add_argument("--fraction", type=float, default=0.05)
    ap.add_argument("--walk", choices=("kollagen", "grid3d"), default="kollagen")
    ap.add_argument("--seed", type=int, default=1)
    args = ap.parse_args()
    from studio.solve import solve
    from studio.synth import synthesize

    doc = synth_config_to_json(preset("multi3500x8"))
    doc["number_of_agents"], doc["number_of_steps"] = args.agents, args.steps
    doc["agent_parameters"]["agent_specific"] = doc["agent_parameters"]["agent_specific"][: args.agents]
    doc["studio"] = {
        "version": 1,
        "walk": args.walk,
        "outliers": {"intra_fraction": args.fraction, "inter_fraction": args.fraction, "seed": args.seed},
    }
    cfg = parse_synth_config(doc, name="gnc_bench")
    with tempfile.TemporaryDirectory() as tmp:
        t0 = time.perf_counter()
        res = synthesize(cfg, Path(tmp) / "data", rrd=False, jobs=1)
        t1 = time.perf_counter()
        sol = solve(res.dataset_dir, Path(tmp) / "solved", method="gnc")
        t2 = time.perf_counter()
    planted = {tuple(r): k for r, k in zip(res.outliers.rows.tolist(), res.outliers.kinds)}
    rejected = {tuple(r) for r in (sol.rejected.tolist() if sol.rejected is not None else [])}
    counts = res.output.graph.edge_counts()
    closures = counts["intra_loop_closures"] + counts["inter_loop_closures"]
    hit = rejected & set(planted)
    print(
        f"{args.walk}: {args.agents} agents x {args.steps} steps, {closures} loop closures, "
        f"{len(planted)} planted outliers; synth {t1 - t0:.2f} s, gnc {t2 - t1:.2f} s, "
        f"peak {resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024:.0f} MiB"
    )
    print(
        f"rejected {len(rejected)}: precision {len(hit) / max(len(rejected), 1):.3f}, "
        f"recall {len(hit) / max(len(planted), 1):.3f}"
    )
    for kind in ("random", "aliasing"):
        mine = {r for r, k in planted.items() if k == kind}
        print(f"  {kind:9} planted {len(mine):4d}  rejected {len(mine & rejected):4d}")


if __name__ == "__main__":
    main()
