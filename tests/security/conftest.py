"""The attack suite's fixtures: an isolated cache and runtime folder per test (other developers' runs are not ours)."""

from __future__ import annotations

from pathlib import Path

import pytest


@pytest.fixture(autouse=True)
def _isolated(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("DIVE_CACHE_DIR", str(tmp_path / "cache"))
    monkeypatch.setenv("DIVE_RUNTIME_DIR", str(tmp_path / "runtime"))
    monkeypatch.delenv("DIVE_URL", raising=False)
    monkeypatch.delenv("DIVE_KEY_FILE", raising=False)
