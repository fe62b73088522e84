"""A registry entry's reference to code that is imported only when used.

The registries (solve methods, convert sources) declare every plug-in in one place; importing each
plug-in's module to fill them would load numpy, the readers and the solvers' libraries into every
command, ``studio --version`` included. A :class:`Lazy` names the module and the attribute instead:
calling it (or :meth:`Lazy.get`) imports the module then. :class:`LazyMapping` does the same for a
mapping constant (a source's default body frames).
"""

from __future__ import annotations

import importlib
from collections.abc import Iterator, Mapping
from dataclasses import dataclass
from typing import Any

__all__ = ["Lazy", "LazyMapping"]


@dataclass(frozen=True)
class Lazy:
    """``module.attr``, imported at the first call (then cached by Python's module table)."""

    module: str
    attr: str

    def get(self) -> Any:
        return getattr(importlib.import_module(self.module), self.attr)

    def __call__(self, *args: Any, **kwargs: Any) -> Any:
        return self.get()(*args, **kwargs)

    def __repr__(self) -> str:
        return f"{self.module}.{self.attr}"


class LazyMapping(Mapping[str, Any]):
    """A read-only mapping ``module.attr``, imported when first read."""

    def __init__(self, module: str, attr: str) -> None:
        self._ref = Lazy(module, attr)

    def _target(self) -> Mapping[str, Any]:
        target: Mapping[str, Any] = self._ref.get()
        return target

    def __getitem__(self, key: str) -> Any:
        return self._target()[key]

    def __iter__(self) -> Iterator[str]:
        return iter(self._target())

    def __len__(self) -> int:
        return len(self._target())

    def __repr__(self) -> str:
        return f"LazyMapping({self._ref!r})"
