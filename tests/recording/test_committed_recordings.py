"""The committed recordings in ``recordings/`` are the regression baseline: regenerate and compare.

Each entry of :data:`CANONICAL` makes one recording from scratch. The test checks, for each:
``rerun rrd verify`` on the committed file, the committed file against its committed fingerprint,
the regenerated file against that fingerprint (exact, per entity and component), and
``rerun rrd compare --unordered`` between the two files.

After an intended change, rewrite the baseline with ``STUDIO_BLESS=1 pytest tests/recording/test_committed_recordings.py``
and commit ``recordings/``.
"""

from __future__ import annotations

import os
import shutil
from collections.abc import Callable
from pathlib import Path

import pytest

from studio.recording.rrd_checks import fingerprint_rrd, read_fingerprint, rrd_compare, rrd_verify, write_fingerprint
from studio.synth import load_synth_config, synthesize

REPO = Path(__file__).resolve().parent.parent.parent
RECORDINGS = REPO / "recordings"
DATA = Path(__file__).resolve().parent.parent / "data" / "configs"


def _synth(config: Path) -> Callable[[Path], Path]:
    def make(tmp: Path) -> Path:
        return synthesize(load_synth_config(config), tmp).rrd_path

    return make


def _convert_tum(folder: Path, name: str) -> Callable[[Path], Path]:
    def make(tmp: Path) -> Path:
        from studio.convert import ConvertConfig, convert
        from studio.converters.build import GraphOptions

        inputs = tuple(str(p) for p in sorted(folder.glob("*.tum")))
        cfg = ConvertConfig("tum", inputs, (), GraphOptions(seed=7, outlier_fraction=0.05))
        return convert(cfg, tmp / name).rrd_path

    return make


#: name -> function that writes the recording under a temporary folder and returns its path.
#: One line per committed recording (``recordings/<name>.rrd``, ``.fingerprint``, ``.command``).
CANONICAL: dict[str, Callable[[Path], Path]] = {
    "small3x100": _synth(DATA / "small3x100.json"),
    "three_loops": _convert_tum(DATA.parent / "trajectories", "three_loops"),
}


def _diff(expected: dict[str, str], actual: dict[str, str]) -> str:
    lines = [f"missing: {k}" for k in sorted(expected.keys() - actual.keys())]
    lines += [f"unexpected: {k}" for k in sorted(actual.keys() - expected.keys())]
    lines += [f"changed: {k}" for k in sorted(expected.keys() & actual.keys()) if expected[k] != actual[k]]
    return "\n".join(lines[:40])


@pytest.mark.parametrize("name", sorted(CANONICAL))
def test_committed_recording_is_reproduced_exactly(name, tmp_path):
    rrd = RECORDINGS / f"{name}.rrd"
    fp_path = RECORDINGS / f"{name}.fingerprint"
    fresh = CANONICAL[name](tmp_path)
    if os.environ.get("STUDIO_BLESS") == "1":
        shutil.copyfile(fresh, rrd)
        write_fingerprint(fingerprint_rrd(rrd), fp_path)
    assert (RECORDINGS / f"{name}.command").read_text().strip(), "say how the recording was made"
    assert rrd.stat().st_size < 1_000_000, "keep committed recordings small"

    rrd_verify(rrd)
    expected = read_fingerprint(fp_path)
    committed = fingerprint_rrd(rrd)
    assert committed == expected, f"{rrd} does not match {fp_path.name}:\n{_diff(expected, committed)}"
    regenerated = fingerprint_rrd(fresh)
    assert regenerated == expected, (
        f"regenerated {name} differs from the committed recording (STUDIO_BLESS=1 to accept):\n"
        f"{_diff(expected, regenerated)}"
    )
    rrd_compare(rrd, fresh)
