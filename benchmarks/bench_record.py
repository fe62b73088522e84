"""Logging speed of a paper-size dataset: wall seconds, peak memory and file size of its recording.

Usage: python benchmarks/bench_record.py [--repeat N] [PRESET ...]   (default: multi10000x5, 3 runs)

Generation is timed separately; the figure that matters is the logging time (budget: 1.5 s and
30 MB for Multi10000x5, 50,005 poses and 76,134 edges).
"""

from __future__ import annotations

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


def bench(name: str, repeat: int) -> None:
    cfg = preset(name)
    t0 = time.perf_counter()
    graph = generate(cfg).graph
    t_gen = time.perf_counter() - t0
    rss_before = _peak_rss_mb()
    import rerun  # noqa: F401  (import cost is not logging cost)

    from studio.recording.dataset import record_graph

    times = []
    with tempfile.TemporaryDirectory() as tmp:
        for k in range(repeat):
            out = Path(tmp) / f"{cfg.name}-{k}.rrd"
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


def main(argv: list[str]) -> None:
    repeat = 3
    if argv[:1] == ["--repeat"]:
        repeat, argv = int(argv[1]), argv[2:]
    for name in argv or ["multi10000x5"]:
        bench(name, repeat)


if __name__ == "__main__":
    main(sys.argv[1:])
