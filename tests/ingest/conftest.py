"""Ingest test set-up: the corpus builders and a fresh data root per test."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

import pytest

from warehouse.store import DataRoot

_BUILDERS = Path(__file__).parent / "corpus" / "builders.py"


def _load_builders():
    name = "ingest_corpus_builders"
    if name not in sys.modules:
        spec = importlib.util.spec_from_file_location(name, _BUILDERS)
        assert spec is not None
        assert spec.loader is not None
        module = importlib.util.module_from_spec(spec)
        sys.modules[name] = module
        spec.loader.exec_module(module)
    return sys.modules[name]


@pytest.fixture(scope="session")
def corpus():
    """The builders module (``csv_file``, ``data_rows``, ``tdms_file``, ``mcap_file``)."""
    return _load_builders()


@pytest.fixture
def root(tmp_path: Path) -> DataRoot:
    return DataRoot.resolve(tmp_path / "data")
