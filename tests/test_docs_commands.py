"""The README's and docs' commands run, and the paths and links they name exist.

Every fenced ``studio ...`` line of README.md and docs/*.md (continuation lines joined, ``$ ``
prompts and ``# comments`` dropped) runs, in document order, as ``python -m studio.cli ...`` in one
work folder shared by the documents (README first). That folder holds small stand-ins for the inputs
the docs name (the kollagen presets are replaced by small3x100, a 3-agent x 100-step config with the
same parameters; ``alpha.txt`` and friends are the test trajectories; the S3E, AirMuseum, bag,
EuRoC, KITTI, Kimera-Multi and MR.CLAM inputs are ``studio samples``' layouts, :mod:`studio.samples`) and the outputs several docs start from
(``out/multi3500x8`` from ``studio synth multi3500x8 -o out/``, ``out/three_loops`` from
``recordings/three_loops.command``). Docs repeat ``studio synth ... -o out/``: a command refused
only because its output already exists is run again with ``--force``. A command that fails
otherwise, or names an input that is not here, fails the test: when a doc gains a command with a new
input, add the input to :data:`INPUTS`. Commands that cannot run here are in :data:`SKIP`, each
with its reason.
"""

from __future__ import annotations

import os
import re
import shlex
import shutil
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parent.parent
DOCS = [REPO / "README.md"] + sorted((REPO / "docs").glob("*.md"))
DATA = REPO / "tests" / "data"

#: Leading words of documented commands that are not run, and why. Keep it short.
SKIP: dict[str, str] = {
    "studio view": "opens a viewer window or serves the web viewer until stopped "
    "(tests/studio/test_cli_newcomer.py checks `view` without a display)",
}


def _skip_reason(words: list[str]) -> str | None:
    line = " ".join(words)
    for prefix, reason in SKIP.items():
        if line.startswith(prefix):
            return reason
    if words[:2] == ["studio", "snapshot"]:
        from studio.recording.viewer import vulkan_drivers

        if not vulkan_drivers():
            return "no Vulkan driver on this machine (apt-get install -y mesa-vulkan-drivers)"
    return None


#: Documents whose paths describe where future modules would go, not files that exist.
PATHS_NOT_CHECKED = {"architecture.md": "names where new sources, solvers and views would go"}


# ------------------------------------------------------------------------------------------- inputs


def _preset_standin(work: Path, name: str) -> None:
    # a file named like the preset wins over the preset (load_synth_config), and names the dataset
    shutil.copyfile(DATA / "configs" / "small3x100.json", work / name)


def _tum(work: Path) -> None:
    for src, dst in (("alpha", "alpha.txt"), ("bob", "bob.txt"), ("carol", "carol.txt")):
        shutil.copyfile(DATA / "trajectories" / f"{src}.tum", work / dst)


def _sample(name: str) -> Callable[[Path], None]:
    """The writer of one of ``studio samples``' layouts (:data:`studio.samples.SAMPLES`)."""
    from studio.samples import SAMPLES

    return SAMPLES[name][1]


def _single_g2o(work: Path) -> None:
    """``M3500.g2o`` and ``kitti_00.g2o`` stand-ins: the single g2o of a small kollagen walk."""
    from studio.synth import load_synth_config, synthesize

    res = synthesize(load_synth_config(DATA / "configs" / "small3x100.json"), work / ".g2o_standin", rrd=False)
    single = res.dataset_dir.parent / f"{res.dataset_dir.name}_singleg2o" / f"{res.dataset_dir.name}.g2o"
    for name in ("M3500.g2o", "kitti_00.g2o"):
        shutil.copyfile(single, work / name)


def _vio(work: Path) -> None:
    """``bob_vio.txt``: a drifting estimate of bob's trajectory (5 % scale, 0.002 rad/s of yaw)."""
    from studio.core.trajectory import Trajectory
    from studio.io.tum import read_tum, write_tum
    from tests.converters.synthetic import drifting_estimate

    bob = read_tum(DATA / "trajectories" / "bob.tum")
    p, q = drifting_estimate(bob.stamps_ns, bob.positions_xyz, bob.quat_xyzw, scale=1.05, yaw_rate=0.002, seed=1)
    write_tum(work / "bob_vio.txt", Trajectory("bob", bob.stamps_ns, p, q))


def _cosmo(work: Path) -> None:
    """``kth_r3_00_wifi.jrl``: a JRL file in COSMO-Bench's layout, as jrl's ``Writer`` writes it."""
    from tests.converters.jrl_files import cosmo_team, write_cosmo_jrl

    write_cosmo_jrl(work / "kth_r3_00_wifi.jrl", cosmo_team(poses=40)[0])


def _kimera_rpgo(work: Path) -> None:
    """``Kimera-RPGO/tests/data``: ``robot_a.g2o`` and ``robot_b.g2o`` with GTSAM Symbol keys and
    six-decimal quaternions, as Kimera-RPGO ships them, sharing no edge."""
    folder = work / "Kimera-RPGO" / "tests" / "data"
    folder.mkdir(parents=True)
    info = "100 0 0 0 0 0 100 0 0 0 0 100 0 0 0 400 0 0 400 0 400"
    quat = "0.000000 0.000000 0.049979 0.998750"  # a yaw of 0.1 rad
    for robot, n in (("a", 6), ("b", 5)):
        keys = [ord(robot) << 56 | i for i in range(n)]
        lines = [f"VERTEX_SE3:QUAT {k} {i:.6f} 0.000000 0.000000 {quat}" for i, k in enumerate(keys)]
        lines += [f"EDGE_SE3:QUAT {a} {b} 1.000000 0.000000 0.000000 {quat} {info}" for a, b in zip(keys, keys[1:])]
        lines.append(f"EDGE_SE3:QUAT {keys[-1]} {keys[1]} -3.000000 0.100000 0.000000 {quat} {info}")
        (folder / f"robot_{robot}.g2o").write_text("\n".join(lines) + "\n")


def _toml_block(doc: Path, first_line: str) -> str:
    """The fenced TOML block of ``doc`` that starts with ``first_line``."""
    blocks = re.findall(r"```toml\n(.*?)```", doc.read_text(encoding="utf-8"), flags=re.S)
    return next(b for b in blocks if b.startswith(first_line))


#: What a command may name as an input, and how the stand-in is made in the work folder.
INPUTS: dict[str, Callable[[Path], None]] = {
    "multi3500x8": lambda w: _preset_standin(w, "multi3500x8"),
    "multi10000x5": lambda w: _preset_standin(w, "multi10000x5"),
    "my_config.json": lambda w: shutil.copyfile(DATA / "configs" / "tiny_three.json", w / "my_config.json"),
    "alpha.txt": _tum,
    "S3E_Square_1": _sample("s3e"),
    "AirMuseum_seq": _sample("airmuseum"),
    "run.bag": _sample("bag"),
    "MH_01_easy": _sample("euroc"),
    "poses/00.txt": _sample("kitti"),
    "ground_truth/1014": _sample("kimera-multi"),
    "MRCLAM_Dataset1": _sample("mrclam"),
    "bob_vio.txt": _vio,
    "M3500.g2o": _single_g2o,
    "kth_r3_00_wifi.jrl": _cosmo,
    "Kimera-RPGO/tests/data": _kimera_rpgo,
    # docs/bench.md's small spec (the doc writes it with a heredoc, which this test does not run)
    "small.toml": lambda w: (w / "small.toml").write_text(
        f'datasets = ["{DATA / "configs" / "small3x100.json"}"]\ncases = ["diagonal"]\nmethods = ["gtsam"]\n'
    ),
    # docs/sweep.md's spec, smaller: 2 cells of the multi3500x8 stand-in
    "radius.toml": lambda w: (w / "radius.toml").write_text(
        'name = "radius"\nbase = "multi3500x8"\nsteps = ["evaluate"]\n[grid]\n'
        '"inter_agent_loop_closure_parameters.loop_closure_radius" = [1.0, 2.0]\n'
    ),
    # docs/sweep.md's replay spec, as the doc writes it (its TOML block)
    "replays.toml": lambda w: (w / "replays.toml").write_text(
        _toml_block(REPO / "docs" / "sweep.md", 'name = "replays"')
    ),
}


#: Outputs several docs start from, made before any doc runs (the commands are the docs' own).
SETUP = (
    "studio synth multi3500x8 -o out/",
    "studio convert tum alpha.txt bob.txt carol.txt --seed 7 --outlier-fraction 0.05 -o out/three_loops",
)


def _env() -> dict[str, str]:
    env = dict(os.environ, RERUN_ANALYTICS="0", PYTHONPATH=str(REPO))
    env.pop("DISPLAY", None)
    env.pop("WAYLAND_DISPLAY", None)
    return env


def _run(words: list[str], work: Path) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-m", "studio.cli", *words[1:]],
        cwd=work,
        env=_env(),
        capture_output=True,
        text=True,
        timeout=300,
        stdin=subprocess.DEVNULL,
    )


@pytest.fixture(scope="module")
def work(tmp_path_factory) -> Path:
    root = tmp_path_factory.mktemp("docs") / "work"
    root.mkdir()
    for make in dict.fromkeys(INPUTS.values()):  # each maker once
        make(root)
    (root / "tests").symlink_to(REPO / "tests")
    shutil.copytree(REPO / "recordings", root / "recordings")
    (root / "docs" / "img").mkdir(parents=True)
    for command in SETUP:
        proc = _run(shlex.split(command), root)
        assert proc.returncode == 0, f"setup `{command}`: {proc.stderr}"
    return root


# ----------------------------------------------------------------------------------------- commands


def documented_commands(doc: Path) -> list[tuple[int, str]]:
    """``(line, command)`` of each fenced ``studio`` command of ``doc``."""
    out = []
    in_fence = False
    pending: tuple[int, str] | None = None
    for n, line in enumerate(doc.read_text(encoding="utf-8").splitlines(), start=1):
        if line.lstrip().startswith("```"):
            in_fence = not in_fence
            pending = None
            continue
        if not in_fence:
            continue
        text = line.strip()
        if pending is not None:
            start, head = pending
            joined = head + " " + text.rstrip("\\").strip()
            if text.endswith("\\"):
                pending = (start, joined)
            else:
                out.append((start, joined))
                pending = None
            continue
        if text.startswith("$ "):
            text = text[2:].strip()
        if not re.match(r"studio(\s|$)", text):
            continue
        if text.endswith("\\"):
            pending = (n, text.rstrip("\\").strip())
        else:
            out.append((n, text))
    return out


def _cases() -> list:
    cases = []
    for doc in DOCS:
        cmds = documented_commands(doc)
        if cmds:
            cases.append(pytest.param(doc, cmds, id=doc.relative_to(REPO).as_posix()))
    return cases


def test_the_docs_have_commands_to_run():
    assert sum(len(documented_commands(d)) for d in DOCS) >= 10


@pytest.mark.slow
@pytest.mark.parametrize(("doc", "commands"), _cases())
def test_documented_commands_run(doc: Path, commands: list[tuple[int, str]], work: Path):
    ran = 0
    for line, command in commands:
        words = shlex.split(command, comments=True)
        if _skip_reason(words):
            continue
        proc = _run(words, work)
        if proc.returncode == 2 and "already exists (use --force" in proc.stderr and "--force" not in words:
            proc = _run(words + ["--force"], work)
        assert proc.returncode == 0, (
            f"{doc.name}:{line}: `{command}` exited {proc.returncode}:\n{proc.stderr[-2000:]}{proc.stdout[-500:]}"
        )
        assert "Traceback" not in proc.stderr, f"{doc.name}:{line}: {proc.stderr[-2000:]}"
        ran += 1
    assert ran, f"{doc.name}: every command was skipped"


# ------------------------------------------------------------------------------------ paths, links

_PATH = re.compile(
    r"(?<![\w/.-])((?:tests|benchmarks|docs|studio|recordings|converters|generator)"
    r"/[\w./-]*\w)(::\w+)?"
)
_LINK = re.compile(r"\]\(([^)#\s]+)(?:#[^)]*)?\)")


@pytest.mark.parametrize("doc", DOCS, ids=lambda d: d.relative_to(REPO).as_posix())
def test_named_paths_tests_and_links_exist(doc: Path):
    missing = []
    text = doc.read_text(encoding="utf-8")
    if doc.name not in PATHS_NOT_CHECKED:
        for n, line in enumerate(text.splitlines(), start=1):
            for m in _PATH.finditer(line):
                path, test = REPO / m.group(1), m.group(2)
                if not path.exists():
                    missing.append(f"{doc.name}:{n}: {m.group(1)}")
                elif test and path.is_file() and f"def {test[2:]}(" not in path.read_text(encoding="utf-8"):
                    missing.append(f"{doc.name}:{n}: {m.group(1)}{test}")
    for m in _LINK.finditer(text):
        target = m.group(1)
        if re.match(r"[a-z]+:", target):  # http:, mailto:
            continue
        if not (doc.parent / target).exists():
            line = text[: m.start()].count("\n") + 1
            missing.append(f"{doc.name}:{line}: link {target}")
    assert not missing, "named in the docs but missing:\n" + "\n".join(missing)
