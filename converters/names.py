"""Agent names taken from data or typed by the user, made safe as folder names."""

from __future__ import annotations

from studio.core.errors import ConfigError
from studio.io.names import safe_file_name

__all__ = ["safe_agent_name", "check_agent_name", "RESERVED_NAMES"]

#: Names an agent folder may not take: the files written beside the agent folders.
RESERVED_NAMES = frozenset({"convert.json", "report.json", "outliers.txt", "inter_agent_lc.dat"})


def safe_agent_name(raw: str) -> str:
    """A folder name made from a name found in data: runs of unsafe characters become ``_``.

    The result never holds a path separator, never starts with a dot (so never ``.`` or ``..``) and
    is never empty or one of :data:`RESERVED_NAMES`.
    """
    return safe_file_name(raw, fallback="agent", reserved=RESERVED_NAMES)


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
