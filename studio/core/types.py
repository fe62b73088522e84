"""Type aliases shared by every layer (no behaviour)."""

from __future__ import annotations

import os
from typing import Union

__all__ = ["PathLike"]

#: a path as a caller may give it: ``"out/x.g2o"``, ``Path("out")`` or any ``os.PathLike[str]``
PathLike = Union[str, "os.PathLike[str]"]
