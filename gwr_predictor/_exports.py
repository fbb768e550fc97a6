"""Lazy public names for the subpackages' `__init__` (PEP 562).

Why lazy: `import gwr_predictor.robot` must not load pybullet, nor `gwr_predictor.evaluation`
matplotlib, just because a user wants one small function; the name is imported on first use.
"""

from __future__ import annotations

import importlib
from collections.abc import Callable


def lazy_exports(package: str, exports: dict[str, str]) -> tuple[Callable[[str], object], Callable[[], list[str]]]:
    """`__getattr__` and `__dir__` for `package`, given {public name: submodule that defines it}."""

    def __getattr__(name: str) -> object:
        module = exports.get(name)
        if module is None:
            raise AttributeError(f"module {package!r} has no attribute {name!r}")
        return getattr(importlib.import_module(f"{package}.{module}"), name)

    def __dir__() -> list[str]:
        return sorted(exports)

    return __getattr__, __dir__
