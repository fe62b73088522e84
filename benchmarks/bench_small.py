"""Small datasets, many of them (issue 28): per-dataset time of the in-memory generator and of
writing a dataset, and a batch of replicates, all in this one process.

    python benchmarks/bench_small.py [--config tests/data/configs/small3x100.json] [--steps 60]
        [--repeat 20] [--batch 1000] [--jobs 0]

``--steps`` overrides the config's number_of_steps (60 is the issue's small case). kollagen's own
Python package is not measured here (build it by hand outside the project to compare); the figures
are wall times of this process, the peak its resident memory.
"""

from __future__ import annotations

import argparse
import dataclasses
import resource
import statistics
import tempfile
import time
from pathlib import Path

from studio.synth import generate, generate_many, load_synth_config, synthesize

REPO = Path(__file__).resolve().parents[1]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--config", default=str(REPO / "tests" / "data" / "configs" / "small3x100.json"))
    ap.add_argument("--steps", type=int, default=60)
    ap.add_argument("--repeat", type=int, default=20)
    ap.add_argument("--batch", type=int, default=1000)
    ap.add_argument("--jobs", type=int, default=0, help="processes for the batch (0: the idle cores)")
    args = ap.parse_args()
    cfg = load_synth_config(args.config)
    if args.steps:
        cfg = dataclasses.replace(cfg, number_of_steps=args.steps)
    generate(cfg)  # warm: imports, libm
    mem, disk = [], []
    with tempfile.TemporaryDirectory(dir="/dev/shm" if Path("/dev/shm").is_dir() else None) as tmp:
        for k in range(args.repeat):  # interleaved
            t0 = time.perf_counter()
            generate(cfg, seed=k)
            mem.append(time.perf_counter() - t0)
            t0 = time.perf_counter()
            synthesize(cfg, Path(tmp) / str(k), rrd=False, jobs=1)
            disk.append(time.perf_counter() - t0)
    t0 = time.perf_counter()
    n = sum(1 for _ in generate_many(cfg, range(args.batch), jobs=args.jobs or None))
    batch = time.perf_counter() - t0
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    poses = cfg.number_of_agents * cfg.poses_per_agent
    print(
        f"config: {Path(args.config).name}, {cfg.number_of_agents} agents x {cfg.number_of_steps} steps ({poses} poses)"
    )
    print(
        f"generate (in memory): median {1e3 * statistics.median(mem):.1f} ms, best {1e3 * min(mem):.1f} ms "
        f"({60 / statistics.median(mem):.0f} datasets/min)"
    )
    print(
        f"synthesize (files, RAM disk, no .rrd, one process): median {1e3 * statistics.median(disk):.1f} ms, "
        f"best {1e3 * min(disk):.1f} ms ({60 / statistics.median(disk):.0f} datasets/min)"
    )
    print(f"generate_many: {n} replicates in {batch:.1f} s ({60 * n / batch:.0f} datasets/min)")
    print(f"peak memory: {peak:.0f} MiB resident")


if __name__ == "__main__":
    main()
