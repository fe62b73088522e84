"""The ``command`` method: any external solver that reads one g2o file and writes one (SE-Sync's or
DPGO's example programs, a g2o binary...). The studio writes the problem as a single g2o file with
global ids ``0..n-1``, runs the command with ``{input}`` and ``{output}`` replaced by the two paths,
and reads the output's vertices back (ids must be the same; edges and ``FIX`` lines are ignored).
"""

from __future__ import annotations

import shlex
import tempfile
from pathlib import Path

import numpy as np

from studio.core.errors import ConfigError, FormatError
from studio.core.geometry import planar_poses_to_se3, se3_poses_to_planar
from studio.core.model import PoseKind
from studio.core.units import MAX_SOLUTION_M
from studio.io.g2o import G2oDocument, read_g2o, write_g2o
from studio.runtime.capture import DEFAULT_CAP_BYTES, run_capped
from studio.solvers.options import CommandOptions
from studio.solvers.problem import Iteration, Problem, Solution, SolveOptions, graph_chi2

__all__ = ["solve_command"]


def solve_command(problem: Problem, options: SolveOptions, on_iteration: Iteration | None = None) -> Solution:
    template = options.own_options(CommandOptions).command.strip()
    if not template:
        raise ConfigError("command: method command needs the program to run, e.g. command = 'se-sync {input} {output}'")
    if "{input}" not in template or "{output}" not in template:
        raise ConfigError(f"command: {template!r} must contain {{input}} and {{output}}")
    with tempfile.TemporaryDirectory(prefix="studio-solve-") as tmp:
        src, dst = Path(tmp) / "problem.g2o", Path(tmp) / "solution.g2o"
        write_g2o(
            src,
            G2oDocument(
                problem.kind,
                np.arange(problem.num_vertices),
                problem.initial,
                problem.edge_from,
                problem.edge_to,
                problem.measurements,
                problem.information_upper,
            ),
        )
        argv = [part.replace("{input}", str(src)).replace("{output}", str(dst)) for part in shlex.split(template)]
        try:
            proc = run_capped(argv)  # a program printing gigabytes holds a few KiB here
        except OSError as err:
            raise ConfigError(f"command: cannot run {argv[0]!r} ({err.strerror})") from None
        if proc.returncode != 0:
            tail = (proc.stderr.strip() or proc.stdout.strip()).splitlines()[-1:] or [""]
            printed = proc.stdout_bytes + proc.stderr_bytes
            kept_kib = DEFAULT_CAP_BYTES // 2 // 1024
            cut = f" ({printed:,} bytes of output; the first and last {kept_kib} KiB kept)" if proc.cut else ""
            raise ConfigError(f"command: {argv[0]} exited with status {proc.returncode}: {tail[0][:200]}{cut}")
        if not dst.is_file():
            raise FormatError(f"command: {argv[0]} wrote no {dst.name}")
        doc = read_g2o(dst, edges=False)
    _check_coordinates(doc, f"{dst.name} written by {argv[0]}")
    ids = doc.vertex_ids
    order = np.argsort(ids, kind="stable")
    if not np.array_equal(ids[order], np.arange(problem.num_vertices)):
        raise FormatError(f"command: the solution's vertex ids are not 0..{problem.num_vertices - 1}")
    poses = doc.vertex_poses[order]
    if doc.kind is not problem.kind:
        poses = planar_poses_to_se3(poses) if problem.kind is PoseKind.SE3 else se3_poses_to_planar(poses)
    if on_iteration is not None:
        on_iteration(0, problem.initial)
        on_iteration(1, poses)
    return Solution(
        poses, 1, (graph_chi2(problem, problem.initial), graph_chi2(problem, poses)), notes={"command": template}
    )


def _check_coordinates(doc: G2oDocument, where: str) -> None:
    """Refuse a solution vertex that is not finite or lies beyond :data:`MAX_SOLUTION_M`, naming the
    program's file and the vertex (the check after solving names only the dataset)."""
    coords = doc.vertex_poses[:, 0 : 2 if doc.kind is PoseKind.SE2 else 3]
    bad = np.flatnonzero(~(np.isfinite(doc.vertex_poses).all(axis=1) & (np.abs(coords) <= MAX_SOLUTION_M).all(axis=1)))
    if len(bad):
        raise FormatError(
            f"command: {where}: {len(bad)} vertices, from vertex {int(doc.vertex_ids[bad[0]])}, are not finite "
            f"or lie beyond {MAX_SOLUTION_M:g} m"
        )
