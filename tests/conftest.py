"""Shared fixtures. Tests never touch the network; Rerun's analytics are off."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

os.environ.setdefault("CI", "true")
os.environ["RERUN_ANALYTICS"] = "0"
# long jobs print a plain progress line every few seconds off a terminal; the suite asserts quiet pipes
# (tests/runtime/test_progress.py sets it low where it tests those lines)
os.environ.setdefault("STUDIO_PROGRESS_INTERVAL_S", "3600")

REPO = Path(__file__).resolve().parent.parent
SHARED = REPO.parent / "shared"
KOLLAGEN_REFERENCE = SHARED / "kollagen-reference"
DATA = Path(__file__).resolve().parent / "data"


def pytest_addoption(parser):
    parser.addoption("--runslow", action="store_true", default=False, help="also run tests marked slow")


def pytest_collection_modifyitems(config, items):
    if config.getoption("--runslow"):
        return
    skip = pytest.mark.skip(reason="slow: run with --runslow (.ci/run does)")
    for item in items:
        if "slow" in item.keywords:
            item.add_marker(skip)


@pytest.fixture(scope="session")
def kollagen_reference() -> Path:
    """../shared/kollagen-reference, or skip when this machine does not have it."""
    if not (KOLLAGEN_REFERENCE / "configs").is_dir():
        pytest.skip("../shared/kollagen-reference is not available here")
    return KOLLAGEN_REFERENCE
