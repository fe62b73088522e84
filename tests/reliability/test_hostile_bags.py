"""Damaged and absurd bags, each refused in one line naming the bag, with no traceback or warning:
truncated and garbage files of every storage, a flipped byte in a ROS 2 metadata.yaml, an orientation
component of 1e200 and a latitude of 200 degrees."""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from studio.cli import app
from tests.converters.bags import Msgs, typestore, utm31_to_latlon, write_bag
from tests.converters.synthetic import UTM_EAST, UTM_NORTH, loop_trajectory

STORAGES = ("ros1", "sqlite3", "mcap")


def _ok_bag(root: Path, storage: str, name: str, *, quat_fault: bool = False) -> Path:
    m = Msgs(typestore(storage))
    s, p, q = loop_trajectory(200)
    if quat_fault:
        q = q.copy()
        q[5] = [1e200, 0.0, 0.0, 1.0]
    return write_bag(
        root / name, storage, {"/odom": [(int(t), m.Odometry(int(t), pp, qq)) for t, pp, qq in zip(s, p, q)]}
    )


def _damaged(root: Path, storage: str, kind: str) -> tuple[Path, str]:
    if kind == "quaternion":
        return _ok_bag(root, storage, f"quat_{storage}", quat_fault=True), "/odom"
    if kind == "latitude":
        m = Msgs(typestore(storage))
        s, p, _ = loop_trajectory(200)
        lat, lon = utm31_to_latlon(p[:, 0] + UTM_EAST, p[:, 1] + UTM_NORTH)
        lat = lat.copy()
        lat[3] = 200.0
        return write_bag(
            root / f"lat_{storage}",
            storage,
            {"/fix": [(int(t), m.NavSatFix(int(t), la, lo, 0.0)) for t, la, lo in zip(s, lat, lon)]},
        ), "/fix"
    path = _ok_bag(root, storage, f"ok_{storage}")
    if kind == "garbage":
        target = root / f"garbage{path.suffix or '.mcap'}"
        target.write_bytes(np.random.default_rng(1).bytes(4000))
        return target, "/odom"
    if path.is_file():  # truncated single-file bag
        target = root / f"trunc{path.suffix}"
        target.write_bytes(path.read_bytes()[: path.stat().st_size // 2])
        return target, "/odom"
    target = root / f"{kind}_{storage}"
    shutil.copytree(path, target)
    if kind == "truncated":
        for f in target.iterdir():
            if f.name != "metadata.yaml":
                f.write_bytes(f.read_bytes()[: f.stat().st_size // 2])
    else:  # metadata: one flipped byte
        meta = target / "metadata.yaml"
        data = bytearray(meta.read_bytes())
        data[10] ^= 0xFF
        meta.write_bytes(bytes(data))
    return target, "/odom"


CASES = [(s, k) for s in STORAGES for k in ("truncated", "garbage", "quaternion", "latitude")] + [
    (s, "metadata") for s in ("sqlite3", "mcap")
]


@pytest.mark.parametrize("storage, kind", CASES)
def test_a_damaged_or_absurd_bag_is_one_line(tmp_path, storage, kind):
    bag, topic = _damaged(tmp_path, storage, kind)
    out = tmp_path / "out"
    res = CliRunner().invoke(
        app, ["convert", "bag", str(bag), "--agent", f"a={topic}", "-o", str(out)], env={"CI": "true"}
    )
    lines = [ln for ln in res.output.splitlines() if ln.strip()]
    assert res.exit_code == 2, res.output
    assert len(lines) == 1 and lines[0].startswith("error: ") and bag.name in lines[0], res.output
    assert "Traceback" not in res.output and "Warning" not in res.output
    assert not out.exists()
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".studio-")]  # nothing staged is left
