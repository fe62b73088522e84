"""MR.CLAM-layout dataset folders for the tests and the docs: the samples' writer
(:mod:`studio.samples`; the data is simulated, the layout is the dataset's)."""

from __future__ import annotations

from studio.samples import BEARING_SIGMA_RAD, LANDMARK_BARCODES, RANGE_SIGMA_M, ROBOT_BARCODES, write_mrclam_dataset
from studio.samples import simulate_mrclam as simulate

__all__ = [
    "BEARING_SIGMA_RAD",
    "LANDMARK_BARCODES",
    "RANGE_SIGMA_M",
    "ROBOT_BARCODES",
    "simulate",
    "write_mrclam_dataset",
]
