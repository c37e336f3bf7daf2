"""The benchmark scripts' tests: a script of ``benchmarks/`` loaded as a module, as it
runs: its folder on the path (its sibling scripts import by name), its module registered
(its dataclasses look it up), and both taken back afterwards with the siblings it
imported."""

from __future__ import annotations

import importlib.util
import sys
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from types import ModuleType

import pytest

BENCHMARKS = Path(__file__).resolve().parents[2] / "benchmarks"


@contextmanager
def _loaded(name: str) -> Iterator[ModuleType]:
    """``benchmarks/<name>.py`` loaded as module ``name`` for the ``with`` block."""
    spec = importlib.util.spec_from_file_location(name, BENCHMARKS / f"{name}.py")
    assert spec is not None
    assert spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    before = set(sys.modules)
    sys.modules[name] = module
    sys.path.insert(0, str(BENCHMARKS))
    try:
        spec.loader.exec_module(module)
        yield module
    finally:
        sys.path.remove(str(BENCHMARKS))
        for loaded in set(sys.modules) - before:
            if (getattr(sys.modules[loaded], "__file__", None) or "").startswith(str(BENCHMARKS)):
                sys.modules.pop(loaded, None)
        sys.modules.pop(name, None)


@pytest.fixture(scope="session")
def benchmark_script():
    """``with benchmark_script("eval_undeclared") as module:`` (see the module docstring)."""
    return _loaded
