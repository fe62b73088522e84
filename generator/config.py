"""kollagen's parameters as frozen dataclasses (pure data, no I/O).

Lengths are in metres (kollagen's "length unit"), angles in radians, information values in
1/m^2 and 1/rad^2. Names follow kollagen's JSON keys so a config reads the same in both tools.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

from studio.core.errors import ConfigError
from studio.generator.extensions import StudioExtensions

__all__ = ["AgentConfig", "InterLoopClosureConfig", "SynthConfig", "estimate_resources", "aliasing_bytes"]


@dataclass(frozen=True)
class AgentConfig:
    """One entry of ``agent_parameters.agent_specific``."""

    std_dev_position: float
    """Odometry noise on the travelled distance of each sub-step [m]."""
    std_dev_angle: float
    """Odometry noise on the heading change of each sub-step [rad]."""
    estimated_information_position: float
    """Information written for odometry x and y [1/m^2]."""
    estimated_information_angle: float
    """Information written for odometry heading [1/rad^2]."""
    random_number_generator_seed: int
    """Seed of the agent's mt19937 (walk and intra-agent loop closures)."""
    std_dev_intra_loop_closure_position: float
    """Noise of intra-agent loop closures, x and y [m]."""
    std_dev_intra_loop_closure_angle: float
    """Noise of intra-agent loop closures, heading [rad]."""
    estimated_information_intra_position: float
    """Information written for intra-agent loop closures, x and y [1/m^2]."""
    estimated_information_intra_angle: float
    """Information written for intra-agent loop closures, heading [1/rad^2]."""
    intra_loop_closure_radius: float
    """Radius of the candidate circle [m]."""
    same_position_intra_loop_closure_probability: float
    """Probability of a loop closure when a grid cell is revisited."""
    intra_loop_closure_probability_scaling: float
    """Scale of ``exp(-5 d^2 / r^2)`` for nearby cells (d in grid cells, r in metres, as kollagen)."""


@dataclass(frozen=True)
class InterLoopClosureConfig:
    """``inter_agent_loop_closure_parameters``."""

    std_dev_loop_closure_position: float
    std_dev_loop_closure_angle: float
    estimated_information_position: float
    estimated_information_angle: float
    loop_closure_radius: float
    loop_closure_probability_scaling: float
    same_position_loop_closure_probability: float
    random_number_generator_seed: int


@dataclass(frozen=True)
class SynthConfig:
    """A whole kollagen config, as kollagen's ``generate`` reads it."""

    number_of_steps: int
    """Random-walk steps per agent; each step has ``step_fragment`` sub-steps (poses)."""
    align: bool
    """Translate agents so their rounded centres of mass coincide with agent 1's."""
    number_of_agents: int
    exact_information_matrix: bool
    """Write the derived odometry information matrix (single g2o only, as kollagen)."""
    stepsize: float
    """Length of one step [m]."""
    step_fragment: int
    """Sub-steps per step; the grid cell is ``stepsize / step_fragment`` metres."""
    allow_retrocession: bool
    """Allow 180 degree turns."""
    agents: tuple[AgentConfig, ...]
    """``number_of_agents`` entries (a single JSON entry is repeated for every agent)."""
    inter: InterLoopClosureConfig
    name: str = field(default="dataset")
    """Dataset name: the stem of the JSON file, or the preset's name."""
    studio: StudioExtensions | None = None
    """The JSON's ``"studio"`` block (3D walk, noise models, outliers), or None: kollagen exactly."""

    def __post_init__(self) -> None:
        if len(self.agents) != self.number_of_agents:
            raise ConfigError("agents must hold number_of_agents entries")

    @property
    def poses_per_agent(self) -> int:
        return self.number_of_steps * self.step_fragment + 1


#: Replicate ``r`` of a config draws every seed ``s`` as ``(s + REPLICATE_SEED_STRIDE * r) mod
#: SEED_MODULUS`` (the walks' and loop closures' mt19937 seeds stay in kollagen's range), so replicates
#: of one config are independent datasets with the config's own seeds as replicate 0.
REPLICATE_SEED_STRIDE = 1_000_003
SEED_MODULUS = 2**31 - 1


def replicate_seed(seed: int, replicate: int) -> int:
    """Seed ``seed`` of replicate ``replicate`` (``replicate_seed(s, 0) == s`` for kollagen's seeds)."""
    return (seed + REPLICATE_SEED_STRIDE * replicate) % SEED_MODULUS


def replicate_config(config: SynthConfig, replicate: int) -> SynthConfig:
    """``config`` with every seed moved to replicate ``replicate`` (0: ``config`` itself); the same
    draw as ``studio sweep``'s ``seed`` parameter."""
    if isinstance(replicate, bool) or not isinstance(replicate, int) or replicate < 0:
        raise ConfigError(f"seed: expected a non-negative integer, got {replicate!r}")
    if replicate == 0:
        return config
    agents = tuple(
        replace(a, random_number_generator_seed=replicate_seed(a.random_number_generator_seed, replicate))
        for a in config.agents
    )
    inter = replace(
        config.inter, random_number_generator_seed=replicate_seed(config.inter.random_number_generator_seed, replicate)
    )
    return replace(config, agents=agents, inter=inter)


#: Rough cost model of one pose, measured on the paper's presets (peak RSS about 170 MB for 50,005
#: poses with 60 MB of interpreter; 1.0-1.3 kB of files per pose), with a safety margin.
MEMORY_BYTES_PER_POSE = 3_000
MEMORY_BYTES_BASE = 80_000_000
#: Per pair of agents (the inter-agent search's bookkeeping): measured 500 agents x 1 step, 125k
#: pairs, +320 MB peak RSS (docs/reliability.md); so 10,000 agents are refused, not grown into.
MEMORY_BYTES_PER_PAIR = 2_500
OUTPUT_BYTES_PER_POSE = 1_500


#: Bytes per candidate ("hit": an occupied cell inside a pose's circle) while loop closures are drawn.
MEMORY_BYTES_PER_HIT = 48
#: Bytes per (pose, window cell) while aliasing outliers compare local patterns
#: (``generator/outliers.local_patterns``: one agent at a time, every pose's ``(2 w F + 1)^2`` window
#: of cell keys and their look-ups; measured 48 B by tracemalloc at 500-5,000 poses and windows of
#: 21-121 cells a side), with margin.
MEMORY_BYTES_PER_ALIAS_CELL = 64


def _radius_cells(radius_m: float, cfg: SynthConfig) -> int:
    return int(math.floor(abs(radius_m * cfg.step_fragment / cfg.stepsize) + 0.5))


def _search_bytes(radius_cells: int, queries: int, table: int) -> float:
    """Memory of one loop-closure search: the circle's lookup grids, the per-pose column ranges and,
    at worst, every table cell inside every pose's circle."""
    side = 2 * radius_cells + 1
    circle = math.pi * radius_cells * radius_cells + side
    return side * side * 24 + queries * side * 32 + queries * min(circle, table) * MEMORY_BYTES_PER_HIT


def aliasing_bytes(cfg: SynthConfig) -> int:
    """Memory of the aliasing outliers' local patterns: one agent's poses times its window's cells
    (0 when no aliasing outlier is asked for)."""
    out = cfg.studio.outliers if cfg.studio is not None else None
    if out is None or not (out.intra_fraction > 0 or out.inter_fraction > 0):
        return 0
    if dict(out.kinds).get("aliasing", 0.0) <= 0:
        return 0
    side = 2 * out.aliasing_window * cfg.step_fragment + 1
    return cfg.poses_per_agent * side * side * MEMORY_BYTES_PER_ALIAS_CELL


def estimate_resources(cfg: SynthConfig) -> tuple[int, int]:
    """``(peak memory bytes, output bytes)`` that generating ``cfg`` will roughly need.

    Poses cost a fixed amount each; each loop-closure search (one agent's intra-agent closures, or one
    pair of agents) is bounded by its circle size, with two searches running at once; aliasing
    outliers add one agent's poses times its window's cells.
    """
    n = cfg.poses_per_agent
    poses = cfg.number_of_agents * n
    searches = [_search_bytes(_radius_cells(a.intra_loop_closure_radius, cfg), n, n) for a in cfg.agents]
    if cfg.number_of_agents > 1:
        searches.append(_search_bytes(_radius_cells(cfg.inter.loop_closure_radius, cfg), n, n))
    pairs = cfg.number_of_agents * (cfg.number_of_agents - 1) // 2
    memory = MEMORY_BYTES_BASE + poses * MEMORY_BYTES_PER_POSE + pairs * MEMORY_BYTES_PER_PAIR + 2 * max(searches)
    memory += aliasing_bytes(cfg)
    return int(memory), poses * OUTPUT_BYTES_PER_POSE
