"""Built-in configs: the two datasets of the kollagen paper (Multi3500x8 and Multi10000x5), a 3D set
(``cube3d``) and an outlier variant of Multi3500x8 (``multi3500x8_outliers``).

The numbers are the paper's parameters (kollagen's ``data/*.json``), written out here so that the
presets work without any file.
"""

from __future__ import annotations

import dataclasses

from studio.generator.config import AgentConfig, InterLoopClosureConfig, SynthConfig
from studio.generator.extensions import Grid3dConfig, OutlierConfig, StudioExtensions

__all__ = ["PRESETS", "preset", "preset_names"]


def _multi3500x8() -> SynthConfig:
    seeds = (1407, 1303, 3097, 7325, 2444, 3832, 1556, 2674)
    info_odo = 1111.111111111111  # 1 / 0.03^2
    agents = tuple(
        AgentConfig(
            std_dev_position=0.03,
            std_dev_angle=0.03,
            estimated_information_position=info_odo,
            estimated_information_angle=info_odo,
            random_number_generator_seed=seed,
            std_dev_intra_loop_closure_position=0.02,
            std_dev_intra_loop_closure_angle=0.02,
            estimated_information_intra_position=2500.0,
            estimated_information_intra_angle=2500.0,
            intra_loop_closure_radius=5.0,
            same_position_intra_loop_closure_probability=0.5,
            intra_loop_closure_probability_scaling=0.05,
        )
        for seed in seeds
    )
    inter = InterLoopClosureConfig(
        std_dev_loop_closure_position=0.025,
        std_dev_loop_closure_angle=0.025,
        estimated_information_position=1599.9999999999998,
        estimated_information_angle=1599.9999999999998,
        loop_closure_radius=5.0,
        loop_closure_probability_scaling=0.05,
        same_position_loop_closure_probability=0.8,
        random_number_generator_seed=2710,
    )
    return SynthConfig(
        number_of_steps=875,
        align=True,
        number_of_agents=8,
        exact_information_matrix=False,
        stepsize=1.0,
        step_fragment=4,
        allow_retrocession=True,
        agents=agents,
        inter=inter,
        name="multi3500x8",
    )


def _multi10000x5() -> SynthConfig:
    seeds = (1406, 1302, 3096, 7324, 2443)
    info_pos = 1890.359168241966  # 1 / 0.023^2
    info_ang = 7561.436672967864  # 1 / 0.0115^2
    agents = tuple(
        AgentConfig(
            std_dev_position=0.023,
            std_dev_angle=0.0115,
            estimated_information_position=info_pos,
            estimated_information_angle=info_ang,
            random_number_generator_seed=seed,
            std_dev_intra_loop_closure_position=0.023,
            std_dev_intra_loop_closure_angle=0.0115,
            estimated_information_intra_position=info_pos,
            estimated_information_intra_angle=info_ang,
            intra_loop_closure_radius=3.0,
            same_position_intra_loop_closure_probability=0.5,
            intra_loop_closure_probability_scaling=0.05,
        )
        for seed in seeds
    )
    inter = InterLoopClosureConfig(
        std_dev_loop_closure_position=0.023,
        std_dev_loop_closure_angle=0.0115,
        estimated_information_position=info_pos,
        estimated_information_angle=info_ang,
        loop_closure_radius=3.0,
        loop_closure_probability_scaling=0.05,
        same_position_loop_closure_probability=1.0,
        random_number_generator_seed=2708,
    )
    return SynthConfig(
        number_of_steps=2500,
        align=True,
        number_of_agents=5,
        exact_information_matrix=False,
        stepsize=1.0,
        step_fragment=4,
        allow_retrocession=False,
        agents=agents,
        inter=inter,
        name="multi10000x5",
    )


def _cube3d() -> SynthConfig:
    """kollagen's ``cube`` wish (paper, Section V) with several agents: four agents walking a 3D grid
    that climb or descend one metre on 15 % of their steps, slightly tilted (0.02 rad pitch and roll),
    with Multi3500x8's noise and a 3 m loop-closure sphere."""
    base = _multi3500x8()
    agents = tuple(dataclasses.replace(a, intra_loop_closure_radius=3.0) for a in base.agents[:4])
    inter = dataclasses.replace(base.inter, loop_closure_radius=3.0)
    studio = StudioExtensions(
        walk="grid3d", grid3d=Grid3dConfig(vertical_probability=0.15, vertical_step=1.0, tilt_std_dev=0.02)
    )
    return dataclasses.replace(
        base, number_of_steps=500, number_of_agents=4, agents=agents, inter=inter, name="cube3d", studio=studio
    )


def _multi3500x8_outliers() -> SynthConfig:
    """Multi3500x8 (kollagen's walk and closures, byte-exact inliers) with 5 % of the intra- and
    inter-agent loop closures made labelled outliers, half random, half perceptual aliasing."""
    studio = StudioExtensions(outliers=OutlierConfig(intra_fraction=0.05, inter_fraction=0.05, seed=1))
    return dataclasses.replace(_multi3500x8(), name="multi3500x8_outliers", studio=studio)


PRESETS = {
    "multi3500x8": _multi3500x8,
    "multi10000x5": _multi10000x5,
    "cube3d": _cube3d,
    "multi3500x8_outliers": _multi3500x8_outliers,
}


def preset_names() -> list[str]:
    return sorted(PRESETS)


def preset(name: str) -> SynthConfig:
    """The preset called ``name`` (case-insensitive); KeyError if there is none.

    The dataset is named ``name`` as given, as kollagen names a dataset after the argument it was
    given (the JSON file's stem): ``studio synth multi3500x8`` writes ``OUT/multi3500x8/``.
    """
    return dataclasses.replace(PRESETS[name.lower()](), name=name)
