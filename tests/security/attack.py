"""What the attack tests share: a `dive run` in a thread against a fake agent, and its recording read back."""

from __future__ import annotations

import json
import threading
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

from mcap.reader import make_reader

from groundstation.recording.recorder import RecorderConfig
from groundstation.run.job import RunConfig, RunResult, run
from groundstation.session.agent_session import SessionConfig
from groundstation.session.events import SessionListener

QUICK = SessionConfig(backoff_s=(0.05, 0.2), link_timeout_s=1.5)


def wait_for(condition: Callable[[], bool], timeout_s: float = 10.0) -> bool:
    deadline = time.monotonic() + timeout_s
    while not condition():
        if time.monotonic() > deadline:
            return False
        time.sleep(0.02)
    return True


class RunInThread:
    """`dive run URL` (the main job, in-process) until stop(); `result` or `error` afterwards."""

    def __init__(self, url: str, out: Path, session: SessionConfig = QUICK, listeners: Sequence[SessionListener] = (),
                 **config: Any) -> None:
        self.listeners = listeners
        self.stop_event = threading.Event()
        self.result: RunResult | None = None
        self.error: BaseException | None = None
        self.config = RunConfig(url=url, recorder=RecorderConfig(directory=out), session=session,
                                backfill_wait_s=3.0, **config)
        self._thread = threading.Thread(target=self._go, daemon=True)
        self._thread.start()

    def _go(self) -> None:
        try:
            self.result = run(self.config, stop=self.stop_event, listeners=self.listeners)
        except BaseException as e:  # noqa: BLE001 handed to the test
            self.error = e

    def stop(self, timeout_s: float = 30.0) -> None:
        self.stop_event.set()
        self.join(timeout_s)

    def join(self, timeout_s: float = 30.0) -> None:
        self._thread.join(timeout_s)
        assert not self._thread.is_alive(), "the run did not end"

    @property
    def alive(self) -> bool:
        return self._thread.is_alive()


def recorded(folder: Path) -> dict[str, list[tuple[int, int, Any]]]:
    """Every recording in `folder` read back with the mcap library: topic -> [(log_time, publish_time, json)]."""
    topics: dict[str, list[tuple[int, int, Any]]] = {}
    for path in sorted(folder.glob("*.mcap")):
        if path.stat().st_size == 0:
            continue
        with path.open("rb") as f:
            for _, channel, message in make_reader(f).iter_messages():
                body = json.loads(message.data) if channel.message_encoding == "json" else message.data
                topics.setdefault(channel.topic, []).append((message.log_time, message.publish_time, body))
    return topics


def sample_indices(folder: Path) -> list[int]:
    return sorted(body["sample"] for _, _, body in recorded(folder).get("/agent/SAMPLE", []))
