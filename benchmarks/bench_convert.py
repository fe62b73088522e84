"""Benchmark of `studio convert` (not a timed test): ``python benchmarks/bench_convert.py [--out DIR] [tum] [bag]``.

1. TUM: 3 agents, 1,000,000 poses in total (100 Hz, UTM-sized coordinates), converted end to end.
2. Bag: a ROS 2 (mcap) bag with 300,000 geometry_msgs/PoseStamped messages on 3 topics.

Inputs are generated once into ``--out`` (default: a temporary folder, removed after) and reused; the figures are
wall-clock seconds of :func:`studio.convert.convert` (reading, building and writing the dataset,
without the recording, whose time is printed separately) and the peak resident memory of the process.
"""

from __future__ import annotations

import argparse
import resource
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from studio.convert import ConvertConfig, convert  # noqa: E402
from tests.converters.synthetic import UTM_EAST, UTM_NORTH, loop_trajectory  # noqa: E402


def make_tum(work: Path, total: int = 1_000_000) -> list[Path]:
    files = []
    for k in range(3):
        path = work / f"agent{k}.txt"
        files.append(path)
        if path.exists():
            continue
        n = total // 3 + (1 if k < total % 3 else 0)
        s, p, q = loop_trajectory(
            n, rate_hz=100.0, radius=50.0, laps=20, phase=k, centre=(UTM_EAST + 10 * k, UTM_NORTH, 30.0)
        )
        sec, ns = np.divmod(s, 1_000_000_000)
        rows = np.column_stack([p, q]).tolist()
        with open(path, "w") as f:
            f.write("# timestamp tx ty tz qx qy qz qw\n")
            f.writelines(f"{a}.{b:09d} {' '.join(map(repr, r))}\n" for a, b, r in zip(sec.tolist(), ns.tolist(), rows))
    return files


def make_bag(work: Path, total: int = 300_000) -> Path:
    from tests.converters.bags import Msgs, typestore, write_bag

    path = work / "poses_bag"
    if path.exists():
        return path
    m = Msgs(typestore("mcap"))
    topics = {}
    for k in range(3):
        s, p, q = loop_trajectory(total // 3, rate_hz=100.0, radius=30.0, laps=10, phase=k)
        topics[f"/robot{k}/pose"] = [(int(t), m.PoseStamped(int(t), pp, qq)) for t, pp, qq in zip(s, p, q)]
    write_bag(path, "mcap", topics)
    return path


def timed(label: str, cfg: ConvertConfig, out: Path) -> None:
    marks: dict[str, float] = {}

    def progress(label: str, done: int, total: int, unit: str = "") -> None:
        marks.setdefault(label, time.perf_counter())

    t0 = time.perf_counter()
    res = convert(cfg, out, force=True, progress=progress, rrd=False)
    dt = time.perf_counter() - t0
    from studio.recording.dataset import record_graph

    t_rec = time.perf_counter()
    record_graph(res.build.graph, out / "bench.rrd", name=out.name)
    rec_s = time.perf_counter() - t_rec
    t_build = marks.get("keyframes and odometry", t0)
    t_write = marks.get("writing", t0)
    poses = sum(len(t) for t in res.trajectories)
    rss = max(resource.getrusage(who).ru_maxrss for who in (resource.RUSAGE_SELF, resource.RUSAGE_CHILDREN)) / 1024
    print(
        f"{label}: {poses} poses -> {res.build.graph.num_poses} keyframes, "
        f"{sum(res.build.graph.edge_counts().values())} edges in {dt:.2f} s (read {t_build - t0:.2f}, "
        f"build {t_write - t_build:.2f}, write {t0 + dt - t_write:.2f}; peak RSS {rss:.0f} MiB); "
        f"the .rrd recording adds {rec_s:.2f} s"
    )


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("what", nargs="*", metavar="{tum,bag}", help="which benchmarks to run (default: both)")
    ap.add_argument(
        "--out",
        type=Path,
        default=None,
        help="folder for the generated inputs and outputs, kept and reused (default: a temporary "
        "folder, removed after)",
    )
    args = ap.parse_args(argv)
    bad = [w for w in args.what if w not in ("tum", "bag")]
    if bad:
        ap.error(f"unknown benchmark {bad[0]!r} (choose from tum, bag)")
    args.what = args.what or ["tum", "bag"]
    if args.out is None:
        with tempfile.TemporaryDirectory(prefix="bench-convert-") as tmp:
            run(Path(tmp), args.what)
    else:
        args.out.mkdir(parents=True, exist_ok=True)
        run(args.out, args.what)


def run(work: Path, what: list[str]) -> None:
    if "tum" in what:
        timed("tum 3 agents", ConvertConfig("tum", make_tum(work)), work / "out_tum")
    if "bag" in what:
        agents = [f"robot{k}=/robot{k}/pose" for k in range(3)]
        timed("bag (mcap) PoseStamped", ConvertConfig("bag", [make_bag(work)], agents), work / "out_bag")


if __name__ == "__main__":
    main()
