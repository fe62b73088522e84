"""Synthetic trajectories for converter tests: the samples' writers (:mod:`studio.samples`), smooth
loops, optionally in UTM-sized coordinates."""

from __future__ import annotations

from studio.samples import UTM_EAST, UTM_NORTH, drifting_estimate, loop_trajectory, tum_text, write_tum_file

__all__ = ["UTM_EAST", "UTM_NORTH", "drifting_estimate", "loop_trajectory", "tum_text", "write_tum_file"]
