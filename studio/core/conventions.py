"""The rotation-error conventions of :mod:`studio.core.residuals`, as words without numpy (the command
line's ``studio check --convention`` is declared from them at start-up; residuals re-exports them)."""

from __future__ import annotations

from typing import Literal

__all__ = ["Convention", "DEFAULT_CONVENTION"]

Convention = Literal["g2o", "rotvec"]
#: The rotation error of g2o's SE3 edges (quaternion vector part), what ``studio check`` uses by default.
DEFAULT_CONVENTION: Convention = "g2o"
