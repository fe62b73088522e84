"""SE-Sync's C++ and `studio solve --method sesync`, side by side in one run, on given g2o files.

    python benchmarks/bench_sesync.py FILE.g2o [FILE.g2o ...] [--sesync PATH] [--repeat 1] [--certify]

SE-Sync's binary is taken from ``--sesync`` or ``$SESYNC_BIN`` (a build of SE-Sync's example that
prints its ``RESULT ... Fxhat=...`` line and writes the estimate, e.g. ``se_sync_cli INPUT OUTPUT``);
without one, its column is left empty. Per file, SE-Sync runs first, then the studio (each
``--repeat`` times, the median kept), every run a fresh process timed end to end (reading, solving,
writing) with its peak resident memory from ``/usr/bin/time -f %M`` where that exists. Printed per
file: wall time of each, the ratio SE-Sync / studio (above 1: the studio is faster), SE-Sync's
``F(x)`` and the studio's ``f``, the published f* where SE-Sync's paper gives one, the final rank of
each staircase, whether the studio certified its answer, and peak memory [MB]; then the median
ratio. ``--certify`` also runs ``studio check FILE --certify`` on SE-Sync's estimate (the studio's
certificate of SE-Sync's answer).

The measurement is only as steady as the machine: on a shared machine run it when it is idle, and
compare ratios of one run, not times of different runs.
"""

from __future__ import annotations

import argparse
import json
import os
import re
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

#: SE-Sync's published optimal values f* (Rosen et al., IJRR 2019, Tables 1-2), by file stem.
PUBLISHED = {
    "manhattan": 6.432e3,
    "city10000": 6.386e2,
    "CSAIL": 3.170e1,
    "intel": 5.235e1,
    "input_INTEL_g2o": 5.235e1,
    "ais2klinik": 1.885e2,
    "sphere2500": 1.687e3,
    "torus3D": 2.423e4,
    "grid3D": 8.432e4,
    "parking-garage": 1.263e0,
    "cubicle": 7.171e2,
    "rim": 5.461e3,
}


def _timed(cmd: list[str]) -> tuple[float, float | None, str]:
    """Wall seconds, peak memory [MB] (None without /usr/bin/time) and stdout of ``cmd``."""
    gnu_time = shutil.which("time") if Path("/usr/bin/time").exists() else None
    with tempfile.NamedTemporaryFile("r", suffix=".mem") as mem:
        full = [gnu_time, "-q", "-f", "%M", "-o", mem.name, *cmd] if gnu_time else cmd
        t0 = time.perf_counter()
        run = subprocess.run(full, capture_output=True, text=True, check=False)
        wall = time.perf_counter() - t0
        if run.returncode != 0:
            raise RuntimeError(f"{' '.join(cmd)} failed ({run.returncode}): {run.stderr.strip()[-300:]}")
        text = Path(mem.name).read_text().strip().splitlines() if gnu_time else []
    peak = int(text[-1]) / 1024 if text and text[-1].isdigit() else None
    return wall, peak, run.stdout


def _sesync(binary: str, g2o: Path, out: Path) -> dict[str, object]:
    wall, peak, text = _timed([binary, str(g2o), str(out)])
    f = re.search(r"Fxhat=([-+0-9.eE]+)", text) or re.search(r"F\(x\): ([-+0-9.eE]+)", text)
    ranks = re.findall(r"level r = (\d+)", text)
    return {
        "wall_s": wall,
        "peak_mb": peak,
        "f": float(f.group(1)) if f else None,
        "rank": int(ranks[-1]) if ranks else None,
    }


def _studio(g2o: Path, out: Path) -> dict[str, object]:
    studio = str(Path(sys.executable).with_name("studio"))
    wall, peak, _ = _timed([studio, "solve", str(g2o), "-o", str(out), "--method", "sesync", "--force"])
    notes = json.loads((out / "solve.json").read_text())["notes"]
    return {
        "wall_s": wall,
        "peak_mb": peak,
        "f": notes["sesync_f"],
        "rank": notes["staircase"][-1]["rank"],
        "certified": notes["certified"],
        "lambda_min": notes["lambda_min"],
    }


def _median(runs: list[dict[str, object]]) -> dict[str, object]:
    out = dict(runs[-1])
    out["wall_s"] = statistics.median(float(r["wall_s"]) for r in runs)  # type: ignore[arg-type]
    return out


def _certify(g2o: Path, estimate: Path) -> str:
    studio = str(Path(sys.executable).with_name("studio"))
    run = subprocess.run(
        [studio, "check", str(g2o), "--certify", str(estimate), "--json"], capture_output=True, text=True
    )
    if run.returncode != 0:
        return f"refused: {run.stderr.strip()}"
    report = json.loads(run.stdout)
    return "certified" if report["certified"] else f"not certified (bound {report['suboptimality_bound']:.3g})"


def _row(name: str, se: dict[str, object] | None, st: dict[str, object], extra: str) -> str:
    def num(v: object, fmt: str) -> str:
        return format(v, fmt) if isinstance(v, (int, float)) else "-"

    ratio = float(se["wall_s"]) / float(st["wall_s"]) if se else None  # type: ignore[arg-type]
    se = se or {}
    return (
        f"| {name} | {num(se.get('wall_s'), '.2f')} | {num(st['wall_s'], '.2f')} | {num(ratio, '.2f')} | "
        f"{num(se.get('f'), '.6g')} | {num(st['f'], '.6g')} | {num(PUBLISHED.get(name), '.4g')} | "
        f"{num(se.get('rank'), 'd')} | {num(st['rank'], 'd')} | {'yes' if st['certified'] else 'no'} | "
        f"{num(se.get('peak_mb'), '.0f')} | {num(st['peak_mb'], '.0f')} |{extra}"
    )


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("files", nargs="+", type=Path)
    ap.add_argument("--sesync", default=os.environ.get("SESYNC_BIN"), help="SE-Sync's binary (INPUT OUTPUT)")
    ap.add_argument("--repeat", type=int, default=1)
    ap.add_argument("--certify", action="store_true", help="certify SE-Sync's estimate with the studio")
    args = ap.parse_args()
    binary = args.sesync if args.sesync and Path(args.sesync).is_file() else None
    head = "| graph | SE-Sync s | studio s | ratio | SE-Sync F(x) | studio f | published f* | SE-Sync rank | studio rank | certified | SE-Sync MB | studio MB |"
    print(head + (" studio's certificate of SE-Sync's estimate |" if args.certify and binary else ""))
    print("|---" * (head.count("|") - 1) + "|" + ("---|" if args.certify and binary else ""))
    ratios = []
    with tempfile.TemporaryDirectory(prefix="bench_sesync") as tmp:
        for g2o in args.files:
            se_runs, st_runs = [], []
            for _ in range(args.repeat):
                if binary:
                    se_runs.append(_sesync(binary, g2o, Path(tmp) / f"{g2o.stem}_sesync.g2o"))
                st_runs.append(_studio(g2o, Path(tmp) / g2o.stem))
            se = _median(se_runs) if se_runs else None
            st = _median(st_runs)
            extra = f" {_certify(g2o, Path(tmp) / f'{g2o.stem}_sesync.g2o')} |" if args.certify and binary else ""
            print(_row(g2o.stem, se, st, extra), flush=True)
            if se:
                ratios.append(float(se["wall_s"]) / float(st["wall_s"]))  # type: ignore[arg-type]
    if ratios:
        print(f"\nmedian ratio SE-Sync / studio: {statistics.median(ratios):.2f} over {len(ratios)} graphs")


if __name__ == "__main__":
    main()
