"""Byte-for-byte agreement with kollagen's own outputs (../shared/kollagen-reference)."""

from __future__ import annotations

import filecmp
from pathlib import Path

import pytest

from studio.synth import load_synth_config, synthesize

REFERENCE_CONFIGS = ["small_three", "exact_noalign", "single_agent", "replicated_agent", "wide_radius"]


def _files(root: Path) -> list[Path]:
    return sorted(p.relative_to(root) for p in root.rglob("*") if p.is_file())


@pytest.mark.parametrize("name", REFERENCE_CONFIGS)
def test_reference_outputs_are_byte_identical(kollagen_reference, tmp_path, name):
    cfg = load_synth_config(kollagen_reference / "configs" / f"{name}.json")
    synthesize(cfg, tmp_path)
    for folder in (name, f"{name}_singleg2o"):
        ref_root = kollagen_reference / "outputs" / folder
        ours_root = tmp_path / folder
        ref_files = _files(ref_root)
        assert ref_files, f"no reference files in {ref_root}"
        assert _files(ours_root) == ref_files
        for rel in ref_files:
            assert filecmp.cmp(ref_root / rel, ours_root / rel, shallow=False), f"{folder}/{rel} differs"
