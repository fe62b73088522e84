"""Leaving the process at once after a command whose every output is durable and closed.

After ``studio synth multi10000x5`` has renamed its fsynced outputs into place, the interpreter's own
exit (module teardown, the garbage collector freeing every object and array, exit handlers) took
another 60-75 ms of wall time on this project's VM until the process was gone (10-11 ms with
``os._exit``: the kernel freeing the memory), a tenth of the whole command, for nothing anyone
needs. A command whose outputs are complete says so with :func:`outputs_final`; the console script
(:mod:`studio._entry`) then ends the process with ``os._exit(0)`` once the command has returned
successfully and its standard streams are flushed (:func:`leave_if_final`).

Only a command that has nothing left for exit handlers to do may call :func:`outputs_final`: every
file it wrote fsynced, closed and renamed into place (the output guard's ``staged_outputs``), no
child process left, no temporary folder left for a finalizer, no server or viewer to stop. Anything
else (a library caller, a test's ``CliRunner``) never sees a difference: only the console script
acts on the mark, and it clears the mark when it starts.
"""

from __future__ import annotations

import os
import sys

__all__ = ["outputs_final", "clear", "leave_if_final"]

_FINAL: list[bool] = []


def outputs_final() -> None:
    """Note that the running command's outputs are all durable and closed (see the module doc)."""
    _FINAL[:] = [True]


def clear() -> None:
    """Forget the mark (the console script's first step)."""
    _FINAL.clear()


def leave_if_final() -> None:
    """``os._exit(0)`` if the command marked its outputs final and the standard streams flush; else
    return (the interpreter's normal exit then reports whatever a flush could not write)."""
    if not _FINAL:
        return
    try:
        for stream in (sys.stdout, sys.stderr):
            if stream is not None:
                stream.flush()
    except (OSError, ValueError):  # a closed or broken stream: let the normal exit say so
        return
    os._exit(0)
