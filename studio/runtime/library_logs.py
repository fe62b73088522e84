"""Log lines of the libraries the studio runs on, set once for the command line.

Rerun's SDK writes its own ERROR/WARN lines (ANSI colours, from Rust, on the process's stderr past
Python) when its file sink fails, e.g. three of them on a full disk before the studio's one line,
which already says what went wrong (every recording is checked once written:
:func:`studio.io.atomic.verify_rrd`). The command line runs with those two crates' logs off.
"""

from __future__ import annotations

import os

__all__ = ["RERUN_LOG_FILTER", "quiet_rerun_writers"]

#: ``RUST_LOG`` the command line runs with unless the caller set one: Rerun's warnings and errors,
#: except those of its file sink and recording stream (``re_log_encoding``, ``re_sdk``), whose
#: failures the studio reports itself, in one line.
RERUN_LOG_FILTER = "warn,re_log_encoding=off,re_sdk=off"


def quiet_rerun_writers() -> None:
    """Rerun's writer logs off unless the caller set ``RUST_LOG`` (call before rerun loads)."""
    os.environ.setdefault("RUST_LOG", RERUN_LOG_FILTER)
