"""The generator seam: what every synthetic-data generator offers the ``studio synth`` pipeline.

A generator turns its config into a :class:`GeneratedDataset`: the :class:`~studio.core.model.PoseGraph`
(written by the pipeline as a multi-g2o folder and a recording) plus optional *extras*, data for
outputs only that generator has (kollagen's single-g2o view). Each extra names the output it becomes
(``OUT/<name><suffix>``); the pipeline (``studio/synth.py``) writes it with the writer registered for
its type, so a generator stays in layer 1 (core only) and never imports a format.

A new generator: a class with ``name``, ``extra_suffixes`` and ``generate`` (see :class:`Generator`),
and, for a new kind of extra, one writer in ``studio/synth.py``'s ``EXTRA_WRITERS``.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Protocol, TypeVar

from studio.core.model import PoseGraph
from studio.runtime.progress import Progress

__all__ = ["Extra", "GeneratedDataset", "Generator"]

ConfigT_contra = TypeVar("ConfigT_contra", contravariant=True)


class Extra(Protocol):
    """Data of one output beyond the multi-g2o folder, written to ``OUT/<name><suffix>``."""

    @property
    def suffix(self) -> str: ...


@dataclass(frozen=True, eq=False)
class GeneratedDataset:
    """A generator's result: the pose graph and the extras it offers (possibly none)."""

    graph: PoseGraph
    extras: tuple[Extra, ...] = ()
    outliers: Any = None
    """The planted outlier loop closures (``studio.generator.outliers.PlantedOutliers``), or None."""


class Generator(Protocol[ConfigT_contra]):
    """A synthetic-data generator (``studio.generator.extended.STUDIO``: kollagen's walk, byte-exact,
    and the studio's modes, :data:`~studio.generator.extended.WALK_MODES`)."""

    name: str

    def extra_suffixes(self, config: ConfigT_contra) -> tuple[str, ...]:
        """The suffixes of the extras ``generate(config)`` will offer (known before any work, so the
        pipeline can refuse existing outputs first)."""
        ...

    def generate(
        self, config: ConfigT_contra, *, jobs: int | None = None, progress: Progress | None = None
    ) -> GeneratedDataset:
        """Generate the dataset; ``jobs`` caps the processes, the result does not depend on it;
        ``progress`` hears of the work done (studio.runtime.progress)."""
        ...
