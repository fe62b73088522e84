"""cslam-studio: collaborative-SLAM pose-graph datasets, synthetic and real."""

__version__ = "0.1.0"
