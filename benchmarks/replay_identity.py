"""Replay outputs before and after a change to the back-ends, byte for byte.

``python benchmarks/replay_identity.py run DATA_DIR OUT_DIR`` replays every dataset folder of
``DATA_DIR`` (``studio synth`` outputs, e.g. of tests/data/configs/small3x100.json) under a few
communication models through every built-in back-end, one output folder per (dataset, model);
``python benchmarks/replay_identity.py compare REF_DIR OUT_DIR`` then compares every file but
``timings.csv`` (solver wall times) and ``ape.png`` bytes with those of a reference run made on
the code before the change, and exits 1 naming the files that differ.
"""

from __future__ import annotations

import sys
from pathlib import Path

MODELS = {"always": "always", "never": "never", "range": "range:15,p=0.7", "period": "range:30,period=20"}
BACKENDS = ["centralized", "independent", "swarm", "dgs"]
SKIP = {"timings.csv"}


def run(data: Path, out: Path) -> None:
    from studio.replay import replay

    for dataset in sorted(p for p in data.iterdir() if p.is_dir() and (p / "agent1").is_dir()):
        for label, model in MODELS.items():
            target = out / f"{dataset.name}-{label}"
            replay(dataset, target, comms=model, backends=BACKENDS, every=10, seed=3, force=True)
            print(target)


def compare(ref: Path, new: Path) -> int:
    ref_files = {p.relative_to(ref) for p in ref.rglob("*") if p.is_file() and p.name not in SKIP}
    new_files = {p.relative_to(new) for p in new.rglob("*") if p.is_file() and p.name not in SKIP}
    bad = sorted(str(p) for p in ref_files ^ new_files)
    bad += sorted(str(p) for p in ref_files & new_files if (ref / p).read_bytes() != (new / p).read_bytes())
    for name in bad:
        print(f"differs: {name}")
    print(f"{len(ref_files & new_files)} files compared, {len(bad)} differ")
    return 1 if bad else 0


if __name__ == "__main__":
    command, a, b = sys.argv[1], Path(sys.argv[2]), Path(sys.argv[3])
    if command == "run":
        run(a, b)
    else:
        sys.exit(compare(a, b))
