"""Where a replay's memory goes: the process's resident high-water mark after each ISAM2 batch.

    python benchmarks/bench_replay_memory.py DATASET --comms rendezvous:rdv3500x8.txt
        [--backends centralized] [--every 50] [--split-closures N] [--out DIR]

Runs ``studio.replay.replay`` in this process and, around every ``IncrementalSolver.add`` (one
ISAM2 batch: the vertices and edges a checkpoint made known), reads ``VmRSS`` and ``VmHWM`` from
``/proc/self/status`` (Linux). Prints each batch that raised the high-water mark or took over a
second, with its new vertices and edges, then the peak and the final team APE per back-end. The
memory the replay holds outside the solvers (dataset, schedule, metrics) is what the process has
before the first batch that raises the mark.

``--split-closures N`` is an experiment for :mod:`studio.solvers.incremental`, not the studio's
behaviour: each batch enters its inter-robot closures N at a time (the first N with the batch's
own vertices and robots' own edges, the rest in further ISAM2 updates), to show what a burst of
closures delivered at one checkpoint costs in one update.
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np


def _status(key: str) -> int:
    """``VmRSS``/``VmHWM`` of this process [MiB]."""
    with open("/proc/self/status", encoding="ascii") as f:
        for line in f:
            if line.startswith(key):
                return int(line.split()[1]) // 1024
    return -1


def _instrument(split: int, log: list[tuple[int, int, int, int, float, int]]) -> None:
    import studio.solvers.incremental as inc

    add = inc.IncrementalSolver.add

    def one(self: Any, new_v: np.ndarray, new_e: np.ndarray, **kwargs: Any) -> None:
        before, t0 = _status("VmHWM"), time.perf_counter()
        add(self, new_v, new_e, **kwargs)
        log.append((len(new_v), len(new_e), _status("VmRSS"), _status("VmHWM"), time.perf_counter() - t0, before))

    def split_add(self: Any, new_v: np.ndarray, new_e: np.ndarray, **kwargs: Any) -> None:
        p, agent = self.problem, self.agent_of_vertex
        inter = agent[p.edge_from[new_e]] != agent[p.edge_to[new_e]]
        closures = new_e[inter]
        one(self, new_v, np.sort(np.concatenate([new_e[~inter], closures[:split]])), **kwargs)
        for k in range(split, len(closures), split):
            one(self, np.zeros(0, dtype=np.int64), closures[k : k + split], **kwargs)

    inc.IncrementalSolver.add = split_add if split else one  # type: ignore[method-assign]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("dataset", type=Path)
    ap.add_argument("--comms", default="always")
    ap.add_argument("--backends", nargs="*", default=["centralized"])
    ap.add_argument("--every", type=int, default=50)
    ap.add_argument("--split-closures", type=int, default=0, help="experiment: closures per ISAM2 update (0: off)")
    ap.add_argument("--out", type=Path, default=None, help="replay folder (default: a temporary one)")
    args = ap.parse_args()
    from studio.replay import replay

    log: list[tuple[int, int, int, int, float, int]] = []
    _instrument(args.split_closures, log)
    out = args.out or Path(tempfile.mkdtemp(prefix="bench-replay-memory-")) / "replay"
    t0 = time.perf_counter()
    res = replay(args.dataset, out, comms=args.comms, backends=args.backends, every=args.every, force=True)
    wall = time.perf_counter() - t0
    print("batch  new_vertices  new_edges  rss_MiB  hwm_MiB  seconds")
    for k, (v, e, rss, hwm, s, before) in enumerate(log):
        if hwm > before or s > 1.0:
            print(f"{k:5d}  {v:12d}  {e:9d}  {rss:7d}  {hwm:7d}  {s:7.1f}")
    print(f"peak {_status('VmHWM')} MiB, {wall:.1f} s, {res.schedule.model}, every {args.every}")
    for run in res.runs:
        print(f"  {run.name}: APE first-pose {run.ape_team_first_pose_m[-1]:.9g} m, se3 {run.ape_team_se3_m[-1]:.9g} m")


if __name__ == "__main__":
    main()
