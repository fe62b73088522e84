"""Pipeline modules that are also their own main function: ``studio.convert(...)`` calls
``studio.convert.convert(...)``, and ``studio.convert.ConvertConfig`` is still the module's class.

A package's submodule named like the function it exposes (``convert``, ``evaluate``, ``solve``,
``check``, ``bench``, ``sweep``) takes that name in the package once it is imported, so ``import
studio; studio.evaluate(...)`` would reach the module, not the function, whenever some other import
had loaded it first. Each such module ends with :func:`make_callable`, so either way the call works.
"""

from __future__ import annotations

import sys
import types
from typing import Any

__all__ = ["make_callable"]


class _CallableModule(types.ModuleType):
    def __call__(self, *args: Any, **kwargs: Any) -> Any:
        return getattr(self, self.__name__.rpartition(".")[2])(*args, **kwargs)


def make_callable(module_name: str) -> None:
    """Make the module ``module_name`` call its same-named function when called."""
    sys.modules[module_name].__class__ = _CallableModule
