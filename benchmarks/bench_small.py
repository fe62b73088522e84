"""Small datasets, many of them (issue 28): per-dataset time of the in-memory generator, of writing a
dataset, and (given its path) of kollagen's own Python package writing the same dataset, side by side
and interleaved in this one process; then a batch of replicates.

    python benchmarks/bench_small.py [--config tests/data/configs/small3x100.json] [--steps 60]
        [--repeat 20] [--batch 1000] [--jobs 0] [--kollagen /folder/holding/kollagen.*.so]

``--steps`` overrides the config's number_of_steps (60 is the issue's small case). ``--kollagen`` is
the folder of kollagen's extension module (``kollagen.generate(json, out, multig2o, singleg2o)``, built
by hand from its repository, never part of the project); its outputs are compared byte for byte with
the studio's. Every figure is a wall time of this process; the output folder is in RAM (/dev/shm)
where there is one; the peak is this process's resident memory.
"""

from __future__ import annotations

import argparse
import dataclasses
import filecmp
import importlib
import json
import os
import resource
import statistics
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

from studio.generator.config import replicate_config
from studio.io.synth_config import synth_config_to_json
from studio.synth import generate, generate_many, load_synth_config, synthesize

REPO = Path(__file__).resolve().parents[1]


def same_files(a: Path, b: Path) -> bool:
    files = sorted(p.relative_to(a) for p in a.rglob("*") if p.is_file())
    return bool(files) and all(filecmp.cmp(a / f, b / f, shallow=False) for f in files)


def load_kollagen(folder: str | None) -> Callable[[str, str, int, int], None] | None:
    if folder is None:
        return None
    sys.path.insert(0, str(Path(folder).resolve()))
    generate_files: Callable[[str, str, int, int], None] = importlib.import_module("kollagen").generate
    return generate_files


def line(label: str, times: list[float], cpu: list[float]) -> str:
    med = statistics.median(times)
    return (
        f"{label:44} median {1e3 * med:7.1f} ms  best {1e3 * min(times):7.1f} ms  ({60 / med:6.0f} datasets/min)"
        f"  cpu median {1e3 * statistics.median(cpu):6.1f} ms"
    )


class Timer:
    """Wall and CPU time of this process around a block, appended to two lists."""

    def __init__(self, wall: list[float], cpu: list[float]) -> None:
        self.wall, self.cpu = wall, cpu

    def __enter__(self) -> None:
        self.t0, self.c0 = time.perf_counter(), time.process_time()

    def __exit__(self, *exc: object) -> None:
        self.wall.append(time.perf_counter() - self.t0)
        self.cpu.append(time.process_time() - self.c0)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--config", default=str(REPO / "tests" / "data" / "configs" / "small3x100.json"))
    ap.add_argument("--steps", type=int, default=60)
    ap.add_argument("--repeat", type=int, default=20)
    ap.add_argument("--batch", type=int, default=1000)
    ap.add_argument("--jobs", type=int, default=0, help="processes for the batch (0: the idle cores)")
    ap.add_argument("--kollagen", default=None, help="folder of kollagen's Python extension module")
    args = ap.parse_args()
    kollagen = load_kollagen(args.kollagen)
    cfg = load_synth_config(args.config)
    if args.steps:
        cfg = dataclasses.replace(cfg, number_of_steps=args.steps)
    generate(cfg)  # warm: imports, libm
    mem: list[float] = []
    disk: list[float] = []
    kol: list[float] = []
    mem_cpu: list[float] = []
    disk_cpu: list[float] = []
    kol_cpu: list[float] = []
    differ: list[int] = []
    with tempfile.TemporaryDirectory(dir="/dev/shm" if Path("/dev/shm").is_dir() else None) as tmp:
        for k in range(args.repeat):  # interleaved, the same replicate for each
            replicate = replicate_config(cfg, k)
            if kollagen is not None:
                cfg_file = Path(tmp) / f"c{k}" / f"{cfg.name}.json"  # kollagen names the dataset after it
                cfg_file.parent.mkdir()
                cfg_file.write_text(json.dumps(synth_config_to_json(replicate), indent=4))
                sys.stdout.flush()
                saved = os.dup(1)  # kollagen prints a line per file on stdout: sent to /dev/null
                devnull = os.open(os.devnull, os.O_WRONLY)
                os.dup2(devnull, 1)
                try:
                    with Timer(kol, kol_cpu):
                        kollagen(str(cfg_file), str(Path(tmp) / f"k{k}"), 1, 1)
                finally:
                    os.dup2(saved, 1)
                    os.close(saved)
                    os.close(devnull)
            with Timer(mem, mem_cpu):
                generate(cfg, seed=k)
            with Timer(disk, disk_cpu):
                synthesize(replicate, Path(tmp) / str(k), rrd=False, jobs=1)
            if kollagen is not None:
                for sub in (cfg.name, f"{cfg.name}_singleg2o"):
                    if not same_files(Path(tmp) / f"k{k}" / sub, Path(tmp) / str(k) / sub):
                        differ.append(k)
    t0 = time.perf_counter()
    n = sum(1 for _ in generate_many(cfg, range(args.batch), jobs=args.jobs or None))
    batch = time.perf_counter() - t0
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    poses = cfg.number_of_agents * cfg.poses_per_agent
    print(f"# {time.strftime('%Y-%m-%d %H:%M')}  {os.cpu_count()} cores  load {os.getloadavg()[0]:.2f}")
    print(
        f"config: {Path(args.config).name}, {cfg.number_of_agents} agents x {cfg.number_of_steps} steps ({poses} poses)"
    )
    if kol:
        print(line("kollagen.generate (files, RAM disk)", kol, kol_cpu))
    print(line("studio synthesize (files, RAM disk, no .rrd)", disk, disk_cpu))
    print(line("studio generate (in memory)", mem, mem_cpu))
    if kol:
        print(
            f"ratios: files {statistics.median(kol) / statistics.median(disk):.1f}x kollagen, "
            f"in memory {statistics.median(kol) / statistics.median(mem):.1f}x kollagen's files (medians of wall time); "
            f"by CPU time {statistics.median(kol_cpu) / statistics.median(disk_cpu):.1f}x and "
            f"{statistics.median(kol_cpu) / statistics.median(mem_cpu):.1f}x"
        )
    if kol:
        print(
            f"bytes: {'the same as kollagen for every seed' if not differ else f'differ from kollagen for seeds {sorted(set(differ))}'}"
            " (a kollagen built with g++ differs: it draws a loop closure's three normals in another order)"
        )
    print(f"generate_many: {n} replicates in {batch:.1f} s ({60 * n / batch:.0f} datasets/min)")
    print(f"peak memory: {peak:.0f} MiB resident")


if __name__ == "__main__":
    main()
