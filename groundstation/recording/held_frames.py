"""What the recorder holds aside: everything before its file opens, and the frames the session did not use."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from groundstation.mcap_io import RAW_ENCODING, McapFileWriter
from groundstation.session.events import Received

RAW_RX_UNUSED_TOPIC = "/raw/rx_unused"  # received frames the session did not use (Recorder.on_unused)


class EarlyFrames:
    """What reaches the recorder before its file opens (the agent's first HELLO names the file), in arrival order.

    Received and sent frames, unused frames and events alike: each kept with the recorder's writer for it, so the
    file opened at the HELLO holds them in the order they came. Never written if no compatible HELLO comes (the
    session gives up within its hello timeout, so they are few).
    """

    def __init__(self) -> None:
        self._held: list[tuple[Callable[[Any], None], Any]] = []

    def keep(self, write: Callable[[Any], None], item: object) -> None:
        self._held.append((write, item))

    def write_all(self) -> None:
        """Hand each held item to its writer, oldest first; nothing is held after."""
        held, self._held = self._held, []
        for write, item in held:
            write(item)


class UnusedFrames:
    """/raw/rx_unused of one open file: the raw bytes of the frames the session received but did not use.

    A SAMPLE or episode frame it already held (a replay after a reconnect), an impossible SAMPLE, the same frame
    twice: kept raw, so /raw/rx and /raw/rx_unused together are every frame the link delivered, in order, and its
    seq gaps can be recounted exactly. The channel is made at the first such frame: most files have none.
    """

    def __init__(self, writer: McapFileWriter) -> None:
        self._writer = writer
        self._channel: int | None = None

    def write(self, received: Received) -> None:
        if self._channel is None:
            self._channel = self._writer.channel(RAW_RX_UNUSED_TOPIC, RAW_ENCODING)
        self._writer.write(self._channel, received.frame.inner, received.host_time_ns, received.agent_time_ns)
