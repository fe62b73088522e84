"""The ``studio`` console script: loads the command line, so that Ctrl-C while it loads ends quietly.

The script generated for ``studio.cli:main`` would import the command line (numpy, typer, ...: a tenth
of a second) before any handler is in place, and Ctrl-C then printed Python's traceback. Here the
import runs under a handler; once the command line runs, typer turns Ctrl-C into exit code 130; once it
has finished, Ctrl-C is ignored while the interpreter exits.

``studio --version`` alone is answered here, before the command line (typer, numpy and the
commands' option declarations: about 0.3 s of CPU on this VM) is loaded.

It also keeps numpy's BLAS to one thread (``OPENBLAS_NUM_THREADS=1`` unless the caller set it), before
numpy loads: the studio spreads work over processes, never over BLAS threads (its matrices are 3x3 to
7x7), and OpenBLAS's idle thread spins for about 0.1 s of CPU after start-up. On two cores that took a
core from the command's own work: measured on ``studio synth multi10000x5``, 0.2-0.3 s less CPU and
about 0.1 s less wall time with one thread.

And it turns off the log lines of Rerun's SDK writer (:func:`studio.runtime.library_logs.quiet_rerun_writers`):
on a failed write (a full disk) its file sink printed three ERROR/WARN lines with ANSI colours before
the studio's own one line, which already says what went wrong.
"""

from __future__ import annotations

import contextlib
import os
import signal
import sys
from typing import NoReturn

from studio.runtime.library_logs import quiet_rerun_writers

__all__ = ["main", "limit_blas_threads"]

_INTERRUPTED = 130  # 128 + SIGINT, as shells report it


def limit_blas_threads() -> None:
    """One OpenBLAS thread unless the caller chose (before numpy loads; see the module doc)."""
    os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")


def _stdout_broken(err: OSError) -> bool:
    """``err`` came from printing to standard output (``typer.echo`` without ``err=True``: a full
    disk behind ``> file``, a closed pipe), not from the command's own work."""
    tb = err.__traceback__
    while tb is not None:
        frame = tb.tb_frame
        module = str(frame.f_globals.get("__name__", ""))
        if frame.f_code.co_name == "echo" and module.endswith("click.utils") and not frame.f_locals.get("err"):
            return True
        tb = tb.tb_next
    return False


def _report_stdout(err: OSError) -> NoReturn:
    """One line for a summary that could not be printed (the command's outputs are in place: the
    output guard renamed them before the summary was printed), exit 2; a closed pipe (``| head``)
    ends quietly. Standard output is pointed at /dev/null so that the interpreter's own flush at
    exit does not print a traceback for the same error."""
    with contextlib.suppress(OSError):
        null = os.open(os.devnull, os.O_WRONLY)
        os.dup2(null, sys.stdout.fileno())
    if isinstance(err, BrokenPipeError):
        sys.exit(0)
    sys.stderr.write(f"studio: standard output: cannot write the summary ({err.strerror or err})\n")
    sys.exit(2)


def main() -> None:
    if sys.argv[1:] == ["--version"]:  # what `studio --version` prints, without loading the command line
        from studio.runtime.version import installed_version

        print(f"studio {installed_version()}")
        signal.signal(signal.SIGINT, signal.SIG_IGN)  # as after any command (below)
        return
    limit_blas_threads()
    quiet_rerun_writers()
    try:
        from studio.cli import main as cli_main
    except KeyboardInterrupt:
        sys.exit(_INTERRUPTED)
    try:
        try:
            cli_main()
        except OSError as err:
            if not _stdout_broken(err):
                raise
            _report_stdout(err)
    finally:
        # The command has finished (its outputs in place, or its error reported): a Ctrl-C now would
        # only interrupt the interpreter's exit handlers, which print "Exception ignored ..." for it.
        signal.signal(signal.SIGINT, signal.SIG_IGN)
