"""cslam-studio: collaborative-SLAM pose-graph datasets, synthetic and real.

The main library calls, one per command (each also in its own module)::

    import studio

    result = studio.synthesize(studio.load_synth_config("multi3500x8"), "out/")
    print(studio.evaluate.evaluate(result.dataset_dir).overall.ape_translation_m.mean)
    graph = studio.read_multi_g2o(result.dataset_dir)          # columns: studio.core.model.PoseGraph

``studio.convert``, ``studio.evaluate``, ``studio.solve``, ``studio.check``, ``studio.bench`` and
``studio.sweep`` are the pipeline modules of those names (as Python's import makes them once any of
them is loaded); their functions are ``studio.evaluate.evaluate`` and so on.

Names are loaded on first use, so ``import studio`` stays as light as the command line's start-up
(numpy, evo, rerun and gtsam are imported by the calls that need them). docs/library.md lists them.
"""

from __future__ import annotations

import importlib

__version__ = "0.1.0"

#: public name -> the module that defines it
_API: dict[str, str] = {
    "synthesize": "studio.synth",
    "load_synth_config": "studio.synth",
    "generate": "studio.synth",
    "generate_many": "studio.synth",
    "convert": "studio.convert",
    "read_convert_config": "studio.convert",
    "ConvertConfig": "studio.convert",
    "evaluate": "studio.evaluate",
    "solve": "studio.solve",
    "check": "studio.check",
    "bench": "studio.bench",
    "load_bench_spec": "studio.bench",
    "sweep": "studio.sweep",
    "record_dataset": "studio.recording.dataset",
    "snapshot": "studio.recording.viewer",
    "read_multi_g2o": "studio.io.multig2o",
    "write_multi_g2o": "studio.io.multig2o",
    "PoseGraph": "studio.core.model",
    "StudioError": "studio.core.errors",
}

__all__ = ["__version__", *_API]


def __getattr__(name: str) -> object:
    module = _API.get(name)
    if module is None:
        raise AttributeError(f"module 'studio' has no attribute {name!r}")
    loaded = importlib.import_module(module)
    # a pipeline named like its function (studio.convert) is the module: importing a submodule
    # binds its name in the package, so the function could not keep the name anyway
    value = loaded if module == f"studio.{name}" else getattr(loaded, name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(__all__)
