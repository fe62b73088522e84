"""The names of the built-in synth presets (``studio synth PRESET``), in the order help lists them.

A plain constant without the generator: the command line's help for ``studio synth`` is declared at
every start-up, and the presets' configs (:data:`studio.generator.presets.PRESETS`, keyed by these
names; tests/architecture/test_startup.py checks the two agree) load the generator and numpy.
"""

from __future__ import annotations

__all__ = ["PRESET_NAMES"]

PRESET_NAMES = ("multi3500x8", "multi10000x5", "cube3d", "multi3500x8_outliers")
