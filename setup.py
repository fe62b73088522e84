"""The one compiled kernel (the loop-closure sampler); everything else is declared in pyproject.toml.

The extension is optional: where no C compiler is found the build goes on without it and the studio
uses the same sampler in Python (the same bytes, slower; ``studio.generator.loop_closures``).
"""

from setuptools import Extension, setup

setup(
    ext_modules=[
        Extension(
            "studio.generator._sampler",
            ["generator/_sampler.c"],
            # no fused multiply-add where the Python sampler rounds twice (aarch64 contracts by
            # default): the bytes must not depend on the build
            extra_compile_args=["-O2", "-ffp-contract=off", "-fno-fast-math"],
            optional=True,
        )
    ]
)
