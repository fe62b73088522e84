"""The one compiled module (kollagen's walk draws, dead-reckoned headings and loop-closure search and
sampler); everything else is declared in pyproject.toml.

The extension is optional: where no C compiler is found the build goes on without it and the studio
uses the numpy and Python code it replaces (the same bytes, slower; ``studio.generator.walk`` and
``studio.generator.loop_closures``).
"""

from setuptools import Extension, setup

setup(
    ext_modules=[
        Extension(
            "studio.generator._sampler",
            ["generator/_sampler.c"],
            # no fused multiply-add where the Python sampler rounds twice (aarch64 contracts by
            # default): the bytes must not depend on the build
            # and no built-in maths (GCC would merge cos and sin of one angle into one sincos call)
            extra_compile_args=["-O2", "-ffp-contract=off", "-fno-fast-math", "-fno-builtin"],
            optional=True,
        )
    ]
)
