"""Agent names taken from data or typed by the user, made safe as folder names."""

from __future__ import annotations

import re

from studio.core.errors import ConfigError

__all__ = ["safe_agent_name", "check_agent_name", "RESERVED_NAMES"]

#: Names an agent folder may not take: the files written beside the agent folders.
RESERVED_NAMES = frozenset({"convert.json", "report.json", "outliers.txt", "inter_agent_lc.dat"})
_SAFE = re.compile(r"[^A-Za-z0-9_.+-]+")


def safe_agent_name(raw: str) -> str:
    """A folder name made from a name found in data: runs of unsafe characters become ``_``.

    The result never holds a path separator, never starts with a dot (so never ``.`` or ``..``) and
    is never empty or one of :data:`RESERVED_NAMES`.
    """
    name = _SAFE.sub("_", re.sub(r"\.{2,}", "_", raw))
    name = re.sub(r"_{2,}", "_", name).strip("_").lstrip(".")
    if not name:
        name = "agent"
    if name in RESERVED_NAMES:
        name = f"agent_{name}"
    return name[:100]


def check_agent_name(name: str, where: str) -> str:
    """Validate a name the user typed (``--agent NAME=SPEC``): it must already be safe."""
    if (
        not name
        or "/" in name
        or "\\" in name
        or ".." in name
        or name.startswith(".")
        or name in RESERVED_NAMES
        or safe_agent_name(name) != name
    ):
        raise ConfigError(
            f"{where}: agent name {name!r} is not a safe folder name "
            "(letters, digits, '_', '-', '+', '.'; no '/', no '..', no leading dot)"
        )
    return name
