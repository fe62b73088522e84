"""kollagen's Fig. 2, measured: generation time against agents, steps and loop-closure radius.

    python benchmarks/bench_scaling.py [--kollagen /path/to/kollagen/generate] [--quick]
                                       [--only agents:2 radius:1] [--repeat N]
                                       [--csv docs/img/scaling.csv] [--png docs/img/scaling.png]

Three sweeps around one base config (Multi3500x8's parameters with --steps steps per agent and
--agents agents): the number of agents, the number of steps per agent and the loop-closure radius
(intra and inter). Each point runs `studio synth CONFIG -o DIR --no-rrd -q` as a whole process (cold
start, every file written) and, with --kollagen, kollagen's `generate CONFIG DIR` on the same JSON.
Writes one CSV row per run (panel, x, tool, wall seconds, peak RSS MiB, poses, edges, load average)
and a PNG with the three panels (matplotlib, Agg). The machine's 1-minute load average before each
run is in the CSV and the printed rows (timings from a shared machine are noisy); the plot's title
names the base config and the cores the runs may use (``taskset -c 1`` makes it one). With
--kollagen the two tools' runs of a point alternate and each point prints kollagen's median over the
studio's (issue 28 asks >= 2x at 2 agents and at R = 1 m: ``--only agents:2 radius:1``).
"""

from __future__ import annotations

import argparse
import csv
import json
import os
import shutil
import statistics
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from timing import run_timed  # noqa: E402  (benchmarks/timing.py, beside this script)

from studio.generator.presets import preset  # noqa: E402
from studio.io.synth_config import synth_config_to_json  # noqa: E402


def config(agents: int, steps: int, radius: float) -> dict:
    doc = synth_config_to_json(preset("multi3500x8"))
    doc["number_of_agents"] = agents
    doc["number_of_steps"] = steps
    spec = doc["agent_parameters"]["agent_specific"][0]
    spec["intra_loop_closure_radius"] = radius
    doc["agent_parameters"]["agent_specific"] = [spec]  # one entry, shared (kollagen replicates it)
    doc["inter_agent_loop_closure_parameters"]["loop_closure_radius"] = radius
    return doc


def count_edges(folder: Path) -> tuple[int, int]:
    poses = edges = 0
    for g2o in folder.glob("agent*/posegraph.g2o"):
        for line in g2o.read_text().splitlines():
            if line.startswith("VERTEX"):
                poses += 1
            elif line.startswith("EDGE"):
                edges += 1
    dat = folder / "inter_agent_lc.dat"
    if dat.is_file():
        edges += sum(1 for ln in dat.read_text().splitlines() if ln.strip())
    return poses, edges


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--kollagen", type=Path, help="kollagen's `generate` binary, to run side by side")
    ap.add_argument("--agents", type=int, default=8, help="agents of the steps and radius sweeps (8)")
    ap.add_argument("--steps", type=int, default=875, help="steps per agent of the agents and radius sweeps (875)")
    ap.add_argument("--radius", type=float, default=5.0, help="loop-closure radius [m] of the other sweeps (5)")
    ap.add_argument("--quick", action="store_true", help="fewer, smaller points (a minute or two)")
    ap.add_argument("--repeat", type=int, default=1, help="runs per point; the median is plotted (1)")
    ap.add_argument("--only", nargs="+", metavar="PANEL:X", help="run only these points, e.g. agents:2 radius:1")
    ap.add_argument("--csv", type=Path, default=Path("scaling.csv"))
    ap.add_argument("--png", type=Path, default=Path("scaling.png"))
    args = ap.parse_args()
    if args.quick:
        sweeps = {"agents": [2, 4, 8], "steps": [250, 500, 1000], "radius": [1.0, 3.0, 5.0]}
    else:
        sweeps = {"agents": [2, 4, 8, 16], "steps": [500, 1000, 2000, 4000], "radius": [1.0, 2.0, 3.0, 5.0, 7.0]}
    if args.only:
        points = [p.partition(":") for p in args.only]
        sweeps = {
            panel: [float(x) if panel == "radius" else int(x) for q, _, x in points if q == panel] for panel in sweeps
        }
    studio = shutil.which("studio") or str(Path(sys.executable).parent / "studio")
    tools = [("studio", lambda cfg, out: [studio, "synth", str(cfg), "-o", str(out), "--no-rrd", "-q"])]
    if args.kollagen:
        tools.append(("kollagen", lambda cfg, out: [str(args.kollagen), str(cfg), str(out)]))
    rows = []
    print(f"# {time.strftime('%Y-%m-%d %H:%M')}  {os.cpu_count()} cores  python {sys.version.split()[0]}")
    print(f"{'panel':7} {'x':>6} {'tool':9} {'wall s':>7} {'peak MiB':>9} {'poses':>7} {'edges':>7} {'load':>5}")
    with tempfile.TemporaryDirectory(prefix="bench_scaling_") as tmp:
        work = Path(tmp)
        for panel, values in sweeps.items():
            for x in values:
                agents = int(x) if panel == "agents" else args.agents
                steps = int(x) if panel == "steps" else args.steps
                radius = float(x) if panel == "radius" else args.radius
                cfg = work / "cfg.json"
                cfg.write_text(json.dumps(config(agents, steps, radius), indent=2))
                runs: dict[str, tuple[list[float], list[float], list[float]]] = {t: ([], [], []) for t, _ in tools}
                for _ in range(args.repeat):  # the tools' runs alternate
                    for tool, cmd in tools:
                        out = work / f"out_{tool}"
                        shutil.rmtree(out, ignore_errors=True)
                        out.mkdir()
                        runs[tool][2].append(os.getloadavg()[0])
                        wall, rss = run_timed(cmd(cfg, out))
                        runs[tool][0].append(wall)
                        runs[tool][1].append(rss)
                for tool, _ in tools:
                    walls, peaks, loads = runs[tool]
                    peak, load = max(peaks), loads[-1]
                    counts = count_edges(work / f"out_{tool}" / "cfg")
                    row = {
                        "panel": panel,
                        "x": x,
                        "tool": tool,
                        "wall_s": round(statistics.median(walls), 3),
                        "peak_mib": round(peak, 1),
                        "poses": counts[0],
                        "edges": counts[1],
                        "load1": round(load, 2),
                    }
                    rows.append(row)
                    print(
                        f"{panel:7} {x:>6} {tool:9} {row['wall_s']:7.2f} {row['peak_mib']:9.0f} "
                        f"{counts[0]:7d} {counts[1]:7d} {load:5.2f}",
                        flush=True,
                    )
                if len(tools) == 2:
                    ratio = statistics.median(runs["kollagen"][0]) / statistics.median(runs["studio"][0])
                    print(f"{panel:7} {x:>6} kollagen / studio (median wall): {ratio:.2f}x", flush=True)
    with open(args.csv, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    plot(rows, args.png, args)
    loads = [r["load1"] for r in rows]
    print(f"wrote {args.csv} and {args.png}; 1-min load {min(loads):.2f}-{max(loads):.2f}")


def plot(rows: list[dict], path: Path, args: argparse.Namespace) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    labels = {"agents": "agents", "steps": "steps per agent", "radius": "loop-closure radius [m]"}
    fig, axes = plt.subplots(1, 3, figsize=(12, 3.6), layout="tight")
    for ax, panel in zip(axes, labels):
        for tool, style in (("studio", "o-"), ("kollagen", "s--")):
            pts = [(r["x"], r["wall_s"]) for r in rows if r["panel"] == panel and r["tool"] == tool]
            if pts:
                ax.plot(*zip(*pts), style, label=tool)
        ax.set_xticks(sorted({r["x"] for r in rows if r["panel"] == panel}))  # the measured points only
        ax.set_xlabel(labels[panel])
        ax.set_ylabel("wall time [s]")
        ax.grid(alpha=0.3)
        if ax.lines:  # a panel left out by --only has none
            ax.legend()
    cores = len(os.sched_getaffinity(0))  # the cores this process and its children may run on
    fig.suptitle(
        f"Generation time (base: Multi3500x8 parameters, {args.agents} agents, {args.steps} steps, "
        f"R = {args.radius:g} m; {cores} {'core' if cores == 1 else 'cores'})",
        fontsize=9,
    )
    fig.savefig(path, dpi=90)


if __name__ == "__main__":
    main()
