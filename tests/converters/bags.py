"""Small ROS 1 and ROS 2 bags written with rosbags' own writers, for the converter tests: the
samples' writers (:mod:`studio.samples`)."""

from __future__ import annotations

from studio.samples import Msgs, typestore, utm31_to_latlon, write_bag

__all__ = ["STORAGES", "Msgs", "typestore", "utm31_to_latlon", "write_bag"]

STORAGES = ("ros1", "sqlite3", "mcap")
