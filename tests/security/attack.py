"""What the attack tests share: a `dive run` in a thread against a fake agent, and its recording read back."""

from __future__ import annotations

import json
import os
import socket
import threading
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path
from typing import Any

from mcap.reader import make_reader

from groundstation.links import make_link
from groundstation.links.hub_auth import new_token, tool_side
from groundstation.links.runs import RunInfo, announce, new_run, withdraw
from groundstation.links.tcp import parse_host_port
from groundstation.recording.recorder import RecorderConfig
from groundstation.run.hub import Hub
from groundstation.run.job import RunConfig, RunResult, run
from groundstation.session.agent_session import Session, SessionConfig
from groundstation.session.events import SessionListener

QUICK = SessionConfig(backoff_s=(0.05, 0.2), link_timeout_s=1.5)


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


@contextmanager
def hub_run(agent_url: str, key: bytes | None = None, **hub_options: Any) -> Iterator[tuple[Session, Hub, RunInfo]]:
    """A run's session with an agent and its hub, announced in $DIVE_RUNTIME_DIR as `dive run` does it."""
    session = Session(make_link(agent_url), SessionConfig(reconnect=False, key=key))
    with session:
        token = new_token()
        hub = Hub(session, token, **hub_options).start()
        session.add_listener(hub)
        info = new_run(os.getpid(), hub.address, agent_url, token)
        announce(info)
        try:
            yield session, hub, info
        finally:
            withdraw(info)
            hub.close()


def tool(key: bytes | None = None, url: str = "hub://") -> Session:
    """A tool's session through the run's hub (as `dive status`, `surface`, `params` open one)."""
    return Session(make_link(url), SessionConfig(reconnect=False, backfill=False, key=key, fetch_params=False))


def attached(info: RunInfo) -> socket.socket:
    """A raw connection to the hub that has passed the handshake (the owner's own, misbehaving tool)."""
    sock = socket.create_connection(parse_host_port(info.hub), timeout=3.0)
    tool_side(sock, info.token, "hub")
    return sock


NOBODY = 65534


def as_another_user() -> dict[str, Any]:
    """subprocess.Popen keywords that run the child as another local user (nobody), for a test running as root."""
    return {"user": NOBODY, "group": NOBODY, "extra_groups": []}
