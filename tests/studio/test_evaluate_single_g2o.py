"""``studio evaluate`` of a single g2o file reads it as every other command does
(:func:`studio.converters.g2o.read_single_g2o`): ids that are not ``0..n-1`` (Kimera-RPGO's Symbol
keys) are renumbered in increasing order, and the estimate ``studio solve`` writes with the file's
own ids is matched by them."""

from __future__ import annotations

import numpy as np
import pytest
from typer.testing import CliRunner

from studio.cli import app
from studio.evaluate import evaluate

runner = CliRunner()

_INFO = "500 0 0 500 0 500"


def _write(tmp_path, ids: list[int]):
    """A planar square walk with a loop closure; vertex k off its truth by 0.1 k m along y."""
    truth = np.array([[0, 0, 0], [1, 0, np.pi / 2], [1, 1, np.pi], [0, 1, -np.pi / 2], [0, 0, 0]], dtype=float)
    lines = [f"VERTEX_SE2 {i} {x} {y + 0.1 * k} {t}" for k, (i, (x, y, t)) in enumerate(zip(ids, truth))]
    for a, b in [(0, 1), (1, 2), (2, 3), (3, 4), (4, 0)]:
        lines.append(f"EDGE_SE2 {ids[a]} {ids[b]} {1.0 if b else 0.0} 0 {np.pi / 2 if b else 0.0} {_INFO}")
    path = tmp_path / "walk.g2o"
    path.write_text("\n".join(lines) + "\n")
    tum = [f"{k} {x} {y} 0 0 0 {np.sin(t / 2)} {np.cos(t / 2)}" for k, (x, y, t) in enumerate(truth)]
    (tmp_path / "walk_GT.tum").write_text("\n".join(tum) + "\n")
    return path


@pytest.mark.parametrize("first", [0, ord("a") << 56])
def test_a_single_g2o_is_scored_by_its_ids_as_every_command_reads_them(tmp_path, first):
    path = _write(tmp_path, [first + k for k in range(5)])
    ev = evaluate(path)
    # the initial estimate: vertex k off by 0.1 k m
    np.testing.assert_allclose(ev.agents[0].ape_translation_m.max, 0.4, atol=1e-12)
    r = runner.invoke(app, ["solve", str(path), "-o", str(tmp_path / "s")])
    assert r.exit_code == 0, r.output
    solved = evaluate(path, estimate=tmp_path / "s")
    assert solved.agents[0].ape_translation_m.max < 1e-9  # the edges are exact: the truth itself
