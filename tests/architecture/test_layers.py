"""The layers of docs/architecture.md, checked on the source: imports only go down.

Every import of every module (top level, inside functions and under ``TYPE_CHECKING`` alike) is
read with :mod:`ast`; a module may import its own package, any lower layer, and nothing else. The
pipelines (modules directly in ``studio/``) may also use each other; ``studio.cli`` is the command
line, and ``studio._entry`` (the console script's entry point, which only loads it) and ``studio.__main__``
(``python -m studio``, which calls it) the top.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]

#: Source folder -> import name (the setuptools package-dir mapping of pyproject.toml).
ROOTS = {"studio": "studio", "generator": "studio.generator", "converters": "studio.converters"}

#: Layer of each package; a pipeline is a module directly in studio/ (rank 5), the CLI is rank 6 and
#: the console script's entry point rank 7. The runtime sits beside the core in layer 0 (rank 0.5):
#: it may import the core, and nothing else of ours; the core imports neither it nor anything else.
RANKS: dict[str, float] = {
    "studio.core": 0,
    # beside the core: may import it, the core may not import the runtime
    "studio.runtime": 0.5,
    "studio.generator": 1,
    "studio.io": 2,
    "studio.converters": 3,
    "studio.solvers": 3,
    "studio.recording": 4,
}
PIPELINE_RANK, CLI_RANK, ENTRY_RANK = 5, 6, 7


def _module_name(path: Path) -> str:
    rel = path.relative_to(REPO)
    root = ROOTS[rel.parts[0]]
    parts = [root, *rel.parts[1:]]
    parts[-1] = parts[-1][:-3]
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(p for p in ".".join(parts).split(".") if p)


def _unit(module: str) -> tuple[str, float]:
    """The layer unit a module belongs to and its rank."""
    if module == "studio":
        return "studio", -1  # the package's __init__ (version only)
    for pkg, rank in RANKS.items():
        if module == pkg or module.startswith(pkg + "."):
            return pkg, rank
    if module == "studio.cli":
        return module, CLI_RANK
    if module == "studio._entry":
        return module, ENTRY_RANK
    if module == "studio.__main__":
        return module, ENTRY_RANK + 1  # python -m studio: calls the entry point
    return module, PIPELINE_RANK


def _modules() -> dict[str, Path]:
    out = {}
    for folder in ROOTS:
        for path in sorted((REPO / folder).rglob("*.py")):
            out[_module_name(path)] = path
    return out


def _imports(path: Path, module: str) -> list[tuple[int, str]]:
    tree = ast.parse(path.read_text(encoding="utf-8"), str(path))
    found = []
    package = module if path.name == "__init__.py" else module.rpartition(".")[0]
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            found += [(node.lineno, a.name) for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")
                base = base[: len(base) - node.level + 1]
                name = ".".join(base + ([node.module] if node.module else []))
            else:
                name = node.module or ""
            found.append((node.lineno, name))
    return [(line, name) for line, name in found if name.split(".")[0] in ("studio", "generator", "converters")]


MODULES = _modules()


def test_every_source_module_is_seen():
    assert "studio.core.model" in MODULES and "studio.generator.kollagen" in MODULES
    assert "studio.converters.build" in MODULES and "studio.cli" in MODULES


@pytest.mark.parametrize("module", sorted(MODULES))
def test_imports_go_down(module):
    unit, rank = _unit(module)
    bad = []
    for line, name in _imports(MODULES[module], module):
        if name.split(".")[0] != "studio":
            bad.append(f"{MODULES[module].name}:{line} imports {name} (generic top-level name; use studio.*)")
            continue
        target_unit, target_rank = _unit(name)
        if target_unit == unit or target_unit == "studio":
            continue
        sideways_pipelines = rank == PIPELINE_RANK and target_rank == PIPELINE_RANK
        if target_rank < rank or sideways_pipelines:
            continue
        bad.append(
            f"{MODULES[module].relative_to(REPO)}:{line}: {module} (layer {rank}) imports {name} (layer {target_rank})"
        )
    assert not bad, "\n".join(bad)


def _library_imports(path: Path) -> list[str]:
    """Every module name ``path`` imports (absolute names, ours and others')."""
    names: list[str] = []
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.Import):
            names += [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom) and not node.level:
            names.append(node.module or "")
    return names


def test_the_core_and_the_runtime_import_no_heavy_library():
    heavy = {"rerun", "evo", "rosbags", "typer", "gtsam", "g2o", "dask", "distributed", "pandas", "scipy"}
    bad = []
    for module, path in MODULES.items():
        if _unit(module)[0] not in ("studio.core", "studio.runtime"):
            continue
        bad += [f"{module}: {n}" for n in _library_imports(path) if n.split(".")[0] in heavy]
    assert not bad, bad


def test_the_core_holds_no_runtime_machinery():
    """Processes, signals, threads and terminal output live in studio.runtime, not beside the model."""
    machinery = {"multiprocessing", "signal", "threading", "ctypes", "subprocess", "rich", "concurrent"}
    bad = []
    for module, path in MODULES.items():
        if _unit(module)[0] != "studio.core":
            continue
        bad += [f"{module}: {n}" for n in _library_imports(path) if n.split(".")[0] in machinery]
    assert not bad, bad
    assert "studio.runtime.parallel" in MODULES and "studio.runtime.progress" in MODULES


def test_the_runtime_sits_beside_the_core():
    assert _unit("studio.runtime.parallel")[1] > _unit("studio.core.model")[1]
    assert _unit("studio.runtime.parallel")[1] < _unit("studio.generator.walk")[1]


def test_only_cli_imports_typer():
    users = [m for m, p in MODULES.items() if "import typer" in p.read_text(encoding="utf-8")]
    assert users == ["studio.cli"]


def test_the_wheel_installs_one_top_level_package():
    from studio.io.spec_file import read_spec_file

    cfg = read_spec_file(REPO / "pyproject.toml")["tool"]["setuptools"]
    packages = cfg["packages"]
    assert {p.split(".")[0] for p in packages} == {"studio"}
    # every package folder of the source tree is listed, so none is silently left out of the wheel
    listed = set(packages)
    found = {m for m, p in MODULES.items() if p.name == "__init__.py"}
    assert found == listed
    assert cfg["package-dir"] == {"studio.generator": "generator", "studio.converters": "converters"}


def test_a_down_to_up_import_is_caught(tmp_path):
    """The walker itself: a core module importing a format would be reported."""
    path = REPO / "studio" / "core" / "model.py"
    fake = tmp_path / "model.py"
    fake.write_text(path.read_text(encoding="utf-8") + "\nfrom studio.io.g2o import read_g2o\n")
    names = [n for _, n in _imports(fake, "studio.core.model")]
    assert "studio.io.g2o" in names
    assert _unit("studio.io.g2o")[1] > _unit("studio.core.model")[1]
