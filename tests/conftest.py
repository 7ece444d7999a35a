"""Every test gets its own runtime folder: a `dive run` a test starts announces its hub there, never where a
developer's own runs (or another test's) would find it."""

from __future__ import annotations

from pathlib import Path

# Imported here, whole, before any test starts a thread: protocol.compiled imports numpy on a daemon thread, and a
# pytest.approx meeting numpy half-imported in sys.modules fails ("partially initialized module 'numpy'"; 3 of 3
# runs of test_session.py's first test under load).
import numpy  # noqa: F401
import pytest


@pytest.fixture(autouse=True)
def _isolated_runs(tmp_path_factory: pytest.TempPathFactory, monkeypatch: pytest.MonkeyPatch) -> Path:
    folder = tmp_path_factory.mktemp("runtime")
    monkeypatch.setenv("DIVE_RUNTIME_DIR", str(folder))
    return folder
