"""Logging speed of a paper-size dataset: wall seconds, peak memory and file size of its recording.

Usage: python benchmarks/bench_record.py [--repeat N] [--out DIR] [PRESET ...]   (default: multi10000x5, 3 runs)

Generation is timed separately; the figure that matters is the logging time (budget: 1.5 s and
30 MB for Multi10000x5, 50,005 poses and 76,134 edges).
"""

from __future__ import annotations

import argparse
import os
import resource
import sys
import tempfile
import time
from pathlib import Path

os.environ.setdefault("CI", "true")
os.environ["RERUN_ANALYTICS"] = "0"

from studio.generator.kollagen import generate  # noqa: E402
from studio.generator.presets import preset  # noqa: E402


def _peak_rss_mb() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0  # Linux: kB


def bench(name: str, repeat: int, out_dir: Path | None = None) -> None:
    cfg = preset(name)
    t0 = time.perf_counter()
    graph = generate(cfg).graph
    t_gen = time.perf_counter() - t0
    rss_before = _peak_rss_mb()
    import rerun  # noqa: F401  (import cost is not logging cost)

    from studio.recording.dataset import record_graph

    times = []
    with tempfile.TemporaryDirectory() as tmp:
        folder = out_dir or Path(tmp)
        folder.mkdir(parents=True, exist_ok=True)
        for k in range(repeat):
            out = folder / f"{cfg.name}-{k}.rrd"
            t0 = time.perf_counter()
            record_graph(graph, out, name=cfg.name)
            times.append(time.perf_counter() - t0)
            size_mb = out.stat().st_size / 1e6
    counts = graph.edge_counts()
    runs = ", ".join(f"{t:.2f}" for t in times)
    print(
        f"{cfg.name}: {graph.num_poses} poses, {sum(counts.values())} edges | "
        f"generate {t_gen:.2f} s | record {max(times):.2f} s worst of [{runs}] s | file {size_mb:.1f} MB | "
        f"peak RSS {_peak_rss_mb():.0f} MB (after generation {rss_before:.0f} MB)"
    )


def main(argv: list[str] | None = None) -> None:
    from studio.generator.presets import preset_names

    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument(
        "presets",
        nargs="*",
        default=["multi10000x5"],
        metavar="PRESET",
        help=f"presets to record (default: multi10000x5; known: {', '.join(preset_names())})",
    )
    ap.add_argument("--repeat", type=int, default=3, help="recordings per preset (default: 3)")
    ap.add_argument(
        "--out", type=Path, default=None, help="folder for the .rrd files (default: a temporary folder, removed after)"
    )
    args = ap.parse_args(argv)
    for name in args.presets:
        if name not in preset_names():
            ap.error(f"unknown preset {name!r} (known: {', '.join(preset_names())})")
        bench(name, args.repeat, args.out)


if __name__ == "__main__":
    main(sys.argv[1:])
