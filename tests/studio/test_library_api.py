"""`import studio` gives the main calls (docs/library.md), lazily, whatever was imported before."""

from __future__ import annotations

import subprocess
import sys

import studio


def test_the_documented_names_are_the_calls_they_say():
    from studio.evaluate import evaluate
    from studio.io.multig2o import read_multi_g2o
    from studio.synth import synthesize

    assert studio.synthesize is synthesize
    assert studio.read_multi_g2o is read_multi_g2o
    assert studio.evaluate is sys.modules["studio.evaluate"] and studio.evaluate.evaluate is evaluate
    assert set(studio.__all__) <= set(dir(studio)) | {"__version__"}


def test_a_pipeline_name_is_its_module_whichever_was_loaded_first(tmp_path):
    """``studio.evaluate`` is the module ``studio.evaluate`` whether it was reached through ``studio``
    or imported first, and its function is ``studio.evaluate.evaluate`` (in a fresh interpreter, so
    nothing was loaded before)."""
    code = (
        "import sys\n"
        "import studio\n"
        "first = studio.evaluate, studio.solve\n"
        "import studio.convert, studio.evaluate, studio.solve, studio.check, studio.bench, studio.sweep\n"
        "assert first == (sys.modules['studio.evaluate'], sys.modules['studio.solve']), first\n"
        "names = ('convert', 'evaluate', 'solve', 'check', 'bench', 'sweep')\n"
        "assert all(callable(getattr(getattr(studio, n), n)) for n in names)\n"
        f"r = studio.synthesize(studio.load_synth_config({str(tmp_path / 'c.json')!r}), {str(tmp_path)!r}, rrd=False)\n"
        "ev = studio.evaluate.evaluate(r.dataset_dir)\n"
        "print(r.dataset_dir, round(ev.overall.ape_translation_m.mean, 9), studio.convert.ConvertConfig.__name__)\n"
    )
    from pathlib import Path

    config = Path(__file__).resolve().parents[1] / "data" / "configs" / "small3x100.json"
    (tmp_path / "c.json").write_text(config.read_text())
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr
    folder, mean, name = out.stdout.split()
    from studio.evaluate import evaluate

    expected = evaluate(folder).overall.ape_translation_m.mean
    assert float(mean) == round(expected, 9) and expected > 0.1 and name == "ConvertConfig"


def test_import_studio_loads_no_pipeline_or_heavy_library():
    code = "import sys, studio; print(sorted(m for m in sys.modules if m.startswith(('studio.', 'numpy', 'rerun'))))"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "[]"


def test_an_unknown_name_is_an_attribute_error():
    import pytest

    with pytest.raises(AttributeError, match="no attribute 'synthesise'"):
        studio.synthesise  # noqa: B018


def test_write_multi_g2o_into_a_missing_folder_is_one_studio_error(tmp_path):
    import pytest

    from studio.core.errors import OutputError

    config = studio.load_synth_config(
        __import__("pathlib").Path(__file__).resolve().parents[1] / "data" / "configs" / "small3x100.json"
    )
    ds = studio.synthesize(config, tmp_path, rrd=False).dataset_dir
    graph = studio.read_multi_g2o(ds)
    with pytest.raises(OutputError, match=r"/missing/x: no such folder"):
        studio.write_multi_g2o(graph, tmp_path / "missing" / "x")
    assert not (tmp_path / "missing").exists()
