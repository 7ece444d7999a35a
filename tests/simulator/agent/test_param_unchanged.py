"""Setting a parameter to the value it has changes nothing on either agent (Python and the C firmware): the learner
keeps what it learned; a real change of a learner parameter restarts it (issue 27 item 2)."""

from __future__ import annotations

import subprocess
import sys
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import pytest

from groundstation.links import make_link
from groundstation.session.agent_session import Session, SessionConfig
from groundstation.session.events import LinkEvent, Received, Sent
from protocol import messages as m
from tests.firmware.core_build import use_firmware_cache

pytestmark = pytest.mark.slow


class _Texts:
    def __init__(self) -> None:
        self.texts: list[str] = []

    def on_received(self, received: Received) -> None:
        if isinstance(received.message, m.Text):
            self.texts.append(received.message.text)

    def on_sent(self, sent: Sent) -> None:
        pass

    def on_event(self, event: LinkEvent) -> None:
        pass


@contextmanager
def _agent(firmware: str) -> Iterator[str]:
    child = subprocess.Popen([sys.executable, "-m", "simulator", "serve", "--tcp", "127.0.0.1:0", "--speed", "max",
                              "--seed", "3", "--firmware", firmware], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                             text=True)
    assert child.stdout is not None
    try:
        address = child.stdout.readline().strip()
        assert address.startswith("tcp://"), child.stderr.read() if child.stderr else ""
        yield address
    finally:
        child.terminate()
        child.wait(10)


@pytest.mark.parametrize("firmware", ["python", "c"])
def test_the_same_value_again_keeps_the_learner(firmware: str, tmp_path_factory: pytest.TempPathFactory,
                                                monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    monkeypatch.setenv("DIVE_CACHE_DIR", str(tmp_path / "cache"))
    if firmware == "c":
        use_firmware_cache(tmp_path_factory)
    texts = _Texts()
    with _agent(firmware) as url, Session(make_link(url), SessionConfig(reconnect=False), [texts]) as session:
        gamma = session.params.get("gamma")
        for _ in range(2):  # the value as the table shows it: twice, nothing restarts
            assert session.set_param("gamma", gamma.value).value == gamma.value
        time.sleep(0.3)
        assert not [t for t in texts.texts if "restarted" in t], texts.texts
        session.set_param("gamma", 0.9)  # a real change does restart it, and says so
        deadline = time.monotonic() + 5
        while not [t for t in texts.texts if "restarted" in t] and time.monotonic() < deadline:
            time.sleep(0.05)
        assert [t for t in texts.texts if "restarted" in t], texts.texts
