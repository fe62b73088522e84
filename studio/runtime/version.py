"""The installed version, read without importing the command line (``studio --version``)."""

from __future__ import annotations

__all__ = ["installed_version"]


def installed_version() -> str:
    """The installed distribution's version, or the source tree's where it was not installed."""
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version("cslam-studio")
    except PackageNotFoundError:  # run from a source tree that was not installed
        from studio import __version__

        return __version__
