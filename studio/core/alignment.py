"""How an estimate is put on its ground truth before it is scored (``studio evaluate --align``).

Kept in the core, free of numpy, so the command line can offer the choices without importing the
evaluation code.
"""

from __future__ import annotations

import enum

__all__ = ["Alignment"]


class Alignment(str, enum.Enum):
    """What each alignment measures (see docs/evaluation.md):

    * ``none``: the estimate as it is, in the frame all agents share (the kollagen paper's
      convention). For an optimum this mostly measures a global rotation of the whole map about the
      fixed vertex, which no optimizer can observe.
    * ``first-pose``: each agent's first estimated pose put on its ground truth (one rigid transform
      per agent). Cheap and common, but it leans on one pose per agent: an error in that pose is
      spread over the whole agent.
    * ``se3``: one Umeyama rigid transform over all agents' poses: measures the map's shape.
    * ``sim3``: the same with scale (monocular estimates).
    """

    none = "none"
    first_pose = "first-pose"
    se3 = "se3"
    sim3 = "sim3"
