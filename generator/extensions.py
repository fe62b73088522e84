"""The studio's extensions of a kollagen config (the JSON's ``"studio"`` block), as frozen dataclasses.

Pure data and pure maths (no I/O). kollagen ignores the block, so a config that carries it still runs
in kollagen, minus the extensions. See docs/synth.md ("Beyond kollagen") for the equations.

Noise models are scaled so that their **variance equals the square of kollagen's standard deviation
key** of the class (``std_dev_position``, ``std_dev_angle``, ...): the Gaussian with the same variance
is their Gaussian approximation, and the information written is kollagen's ``estimated_information_*``
key as always (``1 / sigma^2`` in the paper's configs, i.e. the matching Gaussian approximation).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

__all__ = [
    "NoiseModel",
    "OutlierConfig",
    "Grid3dConfig",
    "StudioExtensions",
    "NOISE_MODELS",
    "OUTLIER_KINDS",
    "INFORMATION_FRAMES",
    "EXTENSIONS_VERSION",
    "noise_variance",
    "sample_noise",
]

#: The version of the ``"studio"`` block this code reads.
EXTENSIONS_VERSION = 1
NOISE_MODELS = ("gaussian", "student_t", "laplace", "mixture")
OUTLIER_KINDS = ("random", "aliasing")
INFORMATION_FRAMES = ("kollagen", "measurement")
#: The measurement classes a noise model can be given to.
NOISE_CLASSES = ("odometry", "intra", "inter")


@dataclass(frozen=True)
class NoiseModel:
    """A zero-mean noise distribution of unit variance, scaled by the class's standard deviation.

    * ``gaussian``: N(0, 1) (kollagen's);
    * ``student_t``: ``t_nu * sqrt((nu - 2) / nu)``, ``nu = dof > 2``;
    * ``laplace``: Laplace(0, b) with ``b = 1 / sqrt(2)``;
    * ``mixture``: component k (probability ``weights[k]``) is N(0, (c * scales[k])^2) with
      ``c = 1 / sqrt(sum_k weights[k] scales[k]^2)``.
    """

    model: str = "gaussian"
    dof: float = 0.0
    weights: tuple[float, ...] = ()
    scales: tuple[float, ...] = ()

    @property
    def is_gaussian(self) -> bool:
        return self.model == "gaussian"


def noise_variance(model: NoiseModel) -> float:
    """Variance of the unit-scaled model: 1 by construction (kept as a function for the tests and docs)."""
    if model.model == "mixture":
        c2 = 1.0 / sum(w * s * s for w, s in zip(model.weights, model.scales))
        return sum(w * c2 * s * s for w, s in zip(model.weights, model.scales))
    return 1.0


def sample_noise(model: NoiseModel, rng: np.random.Generator, shape: tuple[int, ...]) -> np.ndarray:
    """Unit-variance draws of ``model`` (multiply by the class's standard deviation)."""
    if model.model == "gaussian":
        return rng.standard_normal(shape)
    if model.model == "student_t":
        nu = model.dof
        return rng.standard_t(nu, shape) * math.sqrt((nu - 2.0) / nu)
    if model.model == "laplace":
        return rng.laplace(0.0, 1.0 / math.sqrt(2.0), shape)
    if model.model == "mixture":
        w = np.asarray(model.weights, dtype=np.float64)
        s = np.asarray(model.scales, dtype=np.float64)
        c = 1.0 / math.sqrt(float(np.sum(w * s * s)))
        comp = rng.choice(len(w), size=shape, p=w / w.sum())
        return rng.standard_normal(shape) * (c * s[comp])
    raise ValueError(f"unknown noise model {model.model!r}")


@dataclass(frozen=True)
class OutlierConfig:
    """Loop closures turned into labelled outliers (``outliers.txt``)."""

    intra_fraction: float = 0.0
    """Fraction of the intra-agent loop closures made outliers (``round(f * n)``)."""
    inter_fraction: float = 0.0
    """Fraction of the inter-agent loop closures made outliers."""
    kinds: tuple[tuple[str, float], ...] = (("random", 0.5), ("aliasing", 0.5))
    """Relative weights of the kinds: ``random`` (the ``to`` vertex replaced by a pose drawn between
    ``random_min_radius`` and ``random_radius`` metres from the true one) and ``aliasing`` (the ``to``
    vertex replaced by a far-away pose with the same heading and the same local grid pattern)."""
    random_radius: float = 10.0
    """[m] Largest distance of a random outlier's wrong vertex from the true one."""
    random_min_radius: float = 2.0
    """[m] Smallest such distance (closer ones would barely be wrong)."""
    aliasing_min_distance: float = 10.0
    """[m] Smallest distance between an aliased place and the true one."""
    aliasing_window: int = 1
    """Half-width, in steps, of the window of grid cells compared for aliasing."""
    seed: int = 0
    """Seed of the outlier draws (numpy ``default_rng``)."""


@dataclass(frozen=True)
class Grid3dConfig:
    """The 3D grid walk: kollagen's planar turns, plus moves up and down."""

    vertical_probability: float = 0.1
    """Probability that a step climbs or descends (half each) instead of moving horizontally."""
    vertical_step: float = 1.0
    """[m] Height of one climbing or descending step (split into ``step_fragment`` sub-steps)."""
    tilt_std_dev: float = 0.0
    """[rad] Standard deviation of the ground truth's pitch and roll (0: level poses)."""
    seed_offset: int = 0
    """Added to every agent's seed for the 3D walk's numpy streams."""


@dataclass(frozen=True)
class StudioExtensions:
    """The ``"studio"`` block."""

    version: int = EXTENSIONS_VERSION
    walk: str = "kollagen"
    """A generator mode: a name of ``studio.generator.extended.WALK_MODES``."""
    grid3d: Grid3dConfig = field(default_factory=Grid3dConfig)
    noise: tuple[tuple[str, NoiseModel], ...] = ()
    """Per class (``odometry``, ``intra``, ``inter``); a class not listed is Gaussian (kollagen's)."""
    outliers: OutlierConfig | None = None
    information_frame: str = "kollagen"
    """``measurement``: kollagen's Exact odometry information rotated into g2o's error frame."""

    def noise_of(self, cls: str) -> NoiseModel:
        return dict(self.noise).get(cls, NoiseModel())

    @property
    def changes_kollagen_bytes(self) -> bool:
        return (
            self.walk != "kollagen"
            or any(not m.is_gaussian for _, m in self.noise)
            or self.outliers is not None
            or self.information_frame != "kollagen"
        )
