"""Child output captured up to a cap (issue 23): the first and last bytes kept, the rest counted."""

from __future__ import annotations

import subprocess
import sys
import time

import pytest

from studio.runtime.capture import run_capped
from tests.machine import bound_s


def _py(code: str) -> list[str]:
    return [sys.executable, "-c", code]


def test_short_output_is_kept_whole():
    run = run_capped(_py("import sys; print('out'); print('err', file=sys.stderr); sys.exit(4)"))
    assert (run.returncode, run.stdout, run.stderr) == (4, "out\n", "err\n")
    assert (run.stdout_bytes, run.stderr_bytes, run.cut) == (4, 4, False)


def test_long_output_keeps_its_first_and_last_bytes_and_counts_the_rest():
    code = "import sys; sys.stdout.write('A' * 1000 + 'B' * 5_000_000 + 'Z' * 1000); sys.stderr.write('e' * 300)"
    run = run_capped(_py(code), cap_bytes=4096)
    assert run.stdout_bytes == 5_002_000 and run.cut
    head, marker, tail = run.stdout.split("\n", 2)
    assert head == "A" * 1000 + "B" * 1048 and tail == "B" * 1048 + "Z" * 1000
    assert marker == f"[... {5_002_000 - 4096:,} bytes cut ...]"
    assert run.stderr == "e" * 300  # each stream has its own cap


def test_a_child_that_outlives_its_timeout_is_killed():
    t0 = time.monotonic()
    with pytest.raises(subprocess.TimeoutExpired):
        run_capped(_py("import time; print('x', flush=True); time.sleep(60)"), timeout_s=1.0)
    assert time.monotonic() - t0 < bound_s(10)


def test_a_missing_program_is_an_oserror():
    with pytest.raises(OSError):
        run_capped(["/nonexistent/studio-no-such-program"])
