"""Fixtures: a scripted fake agent on a real TCP socket, an isolated cache directory."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import pytest

from tests.groundstation.fake_agent import FakeAgent


@pytest.fixture(autouse=True)
def _isolated_cache(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("DIVE_CACHE_DIR", str(tmp_path / "cache"))
    monkeypatch.delenv("DIVE_URL", raising=False)


@pytest.fixture
def fake_agent() -> Iterator[FakeAgent]:
    agent = FakeAgent()
    yield agent
    agent.close()
