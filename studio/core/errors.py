"""The one error tree of cslam-studio.

Every error that bad input can cause is a :class:`StudioError`. Its message is one line that says
what is wrong and where (``file:line`` or a JSON path). The CLI catches the base class once, prints
the message and exits with code 2; any other exception is a bug and keeps its traceback.
"""

from __future__ import annotations

__all__ = [
    "StudioError",
    "ConfigError",
    "FormatError",
    "GraphError",
    "OutputError",
    "EvaluationError",
]


class StudioError(Exception):
    """Base class of every error caused by input the user gave."""


class ConfigError(StudioError):
    """A configuration (JSON file, preset name, option value) is invalid.

    ``option`` names the library option at fault (``lc_radius``), so the command line can name its
    flag (``--lc-radius``) while a config file's reader names the key; ``also`` names other library
    options the message mentions (``partition`` needs ``split``), written as flags the same way."""

    def __init__(self, message: str, *, option: str | None = None, also: tuple[str, ...] = ()) -> None:
        super().__init__(message)
        self.option = option
        self.also = also


class FormatError(StudioError):
    """A file could not be parsed; the message names the file and line."""


class GraphError(StudioError):
    """A pose graph breaks an invariant (lengths, unknown vertices, non-unit quaternions...)."""


class OutputError(StudioError):
    """An output cannot be written (it exists and --force was not given, or the folder is unusable)."""


class BackendError(StudioError):
    """A replay back-end outside the studio (``command:PROGRAM``) ended, hung or answered outside the
    protocol; the message names the back-end and the checkpoint."""


class EvaluationError(StudioError):
    """An estimate cannot be scored against its dataset (vertices or timestamps do not match, no ground truth)."""
