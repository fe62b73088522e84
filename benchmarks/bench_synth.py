"""Time `studio synth` on the paper's presets as whole processes (cold start, every file written).

    python benchmarks/bench_synth.py [--repeat 5] [--kollagen /path/to/kollagen/generate]

Prints, per preset, the median and best wall time, the peak resident memory and every run's time (in
the order they ran). `studio` is
`studio synth PRESET --no-rrd` (exactly kollagen's files); `studio+rrd` is the default command, which
also writes the Rerun recording. With --kollagen, kollagen's own `generate` binary runs side by side on
the same config (written from the preset) and its files are compared byte for byte with ours.
"""

from __future__ import annotations

import argparse
import filecmp
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

PRESETS = ["multi3500x8", "multi10000x5"]


def same_files(a: Path, b: Path) -> bool:
    files = sorted(p.relative_to(a) for p in a.rglob("*") if p.is_file())
    return bool(files) and all(filecmp.cmp(a / f, b / f, shallow=False) for f in files)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--kollagen", type=Path, help="kollagen's `generate` binary, to run side by side")
    ap.add_argument("--presets", nargs="*", default=PRESETS)
    ap.add_argument(
        "--out",
        type=Path,
        default=None,
        help="work folder for the outputs (default: a temporary folder, removed after)",
    )
    args = ap.parse_args()
    studio = shutil.which("studio") or str(Path(sys.executable).parent / "studio")
    print(f"# {time.strftime('%Y-%m-%d')}  {os.cpu_count()} cores  python {sys.version.split()[0]}")
    print(f"{'dataset':14} {'tool':10} {'median s':>9} {'best s':>8} {'peak MiB':>9}  runs")
    for name in args.presets:
        cfg = preset(name)
        with tempfile.TemporaryDirectory() as tmp_dir:
            tmp = Path(tmp_dir) if args.out is None else args.out / name
            tmp.mkdir(parents=True, exist_ok=True)
            rows = {"studio": [], "studio+rrd": [], "kollagen": []}
            peaks = {"studio": 0.0, "studio+rrd": 0.0, "kollagen": 0.0}
            cfg_file = tmp / f"{cfg.name}.json"
            cfg_file.write_text(json.dumps(synth_config_to_json(cfg), indent=4))
            for k in range(args.repeat):
                out = tmp / f"studio{k}"
                wall, peak = run_timed([studio, "synth", name, "-o", str(out / "rrd"), "-q"])
                rows["studio+rrd"].append(wall)
                peaks["studio+rrd"] = max(peaks["studio+rrd"], peak)
                wall, peak = run_timed([studio, "synth", name, "-o", str(out), "-q", "--no-rrd"])
                rows["studio"].append(wall)
                peaks["studio"] = max(peaks["studio"], peak)
                if args.kollagen:
                    kout = tmp / f"kollagen{k}"
                    wall, peak = run_timed([str(args.kollagen), str(cfg_file), str(kout)])
                    rows["kollagen"].append(wall)
                    peaks["kollagen"] = max(peaks["kollagen"], peak)
                    for sub in (cfg.name, f"{cfg.name}_singleg2o"):
                        if not same_files(kout / sub, out / sub):
                            raise SystemExit(f"{sub}: studio and kollagen outputs differ")
                    shutil.rmtree(kout)
                shutil.rmtree(out)
            for tool, walls in rows.items():
                if walls:
                    print(
                        f"{cfg.name:14} {tool:10} {statistics.median(walls):9.2f} {min(walls):8.2f} "
                        f"{peaks[tool]:9.0f}  {len(walls)}: {' '.join(f'{w:.2f}' for w in walls)}"
                    )
            if rows["kollagen"]:
                ratio = statistics.median(rows["kollagen"]) / statistics.median(rows["studio"])
                print(f"{cfg.name:14} speed-up   {ratio:9.2f}x (median kollagen / median studio), outputs identical")


if __name__ == "__main__":
    main()
