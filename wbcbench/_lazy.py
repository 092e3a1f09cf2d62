"""Packages whose public names are imported when first used (PEP 562), so that importing a package, or a light
module of it such as the command line's `commands`, does not import its heavy modules.

    from .._lazy import lazy_exports
    __getattr__, __dir__ = lazy_exports(__name__, {"compare": "compare", "reproduce": "reproduce", ...})

A name that is also a submodule's (`report.compare`, the function of `report/compare.py`) stays the exported
object once loaded, as it did with eager imports: Python's import system sets a package's attribute to a
submodule when that submodule is first imported, which would otherwise replace the function by the module.
"""

from __future__ import annotations

import importlib
import sys
import types
from collections.abc import Callable, Mapping


class _LazyPackage(types.ModuleType):
    """A package module that keeps an exported name bound to its export, not to the same-named submodule."""

    def __setattr__(self, name: str, value) -> None:
        exports = self.__dict__.get("_EXPORTS", {})
        if name in exports and isinstance(value, types.ModuleType) and hasattr(value, name):
            # a submodule (or a module found under that name) is being bound by the import system: bind the export
            # instead (loading it from the module that has just been imported)
            value = getattr(value, name)
        super().__setattr__(name, value)


def lazy_exports(package: str, exports: Mapping[str, str]) -> tuple[Callable, Callable]:
    """Install lazy loading of `exports` (public name -> submodule name, relative to `package`) on the package
    module; returns its module-level `__getattr__` and `__dir__`."""
    module = sys.modules[package]
    module.__dict__["_EXPORTS"] = dict(exports)
    module.__class__ = _LazyPackage

    def __getattr__(name: str):
        sub = exports.get(name)
        if sub is None:
            raise AttributeError(f"module {package!r} has no attribute {name!r}")
        value = getattr(importlib.import_module(f".{sub}", package), name)
        module.__dict__[name] = value
        return value

    def __dir__() -> list[str]:
        return sorted(set(module.__dict__) | set(exports))

    return __getattr__, __dir__
