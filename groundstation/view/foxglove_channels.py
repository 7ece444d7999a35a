"""Every channel of the recording live on a Foxglove server: the recorder's topics, JSON schemas and message bodies."""

from __future__ import annotations

import json
import threading
from collections.abc import Callable
from typing import Any

import foxglove

from groundstation.links.hub import MARKER_CONFIRMATION
from groundstation.recording.recorder import body_json, dump_topic, event_topic, message_json, message_topic
from groundstation.session.dumps import Dump, DumpAssembler
from groundstation.session.events import LinkEvent, Received, Sent
from groundstation.view.foxglove_images import DumpImages
from protocol import Message
from protocol import messages as m
from protocol.cobs import cobs_decode


class FoxgloveChannels:
    """A session listener: each frame, command and event published on the channel the recording would write it to
    (`/agent/SAMPLE`, `/ground/CMD_PAUSE`, `/link`, `/event`, `/marker`, `/dump/VALUES`), and each completed value
    or policy dump also drawn as an image. A channel is encoded only while a client subscribes to it."""

    def __init__(self, context: foxglove.Context,
                 on_parameter: Callable[[m.ParamValue], None] | None = None) -> None:
        self._context = context
        self._lock = threading.Lock()  # channels are made from the session's reader thread and from services
        self._channels: dict[str, foxglove.Channel] = {}
        self._rx: dict[type[Message], foxglove.Channel] = {}
        self._tx: dict[type[Message], foxglove.Channel] = {}
        self._dumps = DumpAssembler()
        self.images = DumpImages(context)
        self._on_parameter = on_parameter
        self.marker_confirmed = threading.Event()  # the run's hub said "marker recorded" (a mark service call)

    def channel(self, topic: str, schema_name: str, schema: dict[str, Any]) -> foxglove.Channel:
        """The channel of `topic`, advertised to clients the first time it is asked for."""
        with self._lock:
            found = self._channels.get(topic)
            if found is None:
                data = json.dumps(schema).encode()
                found = foxglove.Channel(topic, message_encoding="json", context=self._context,
                                         schema=foxglove.Schema(name=schema_name, encoding="jsonschema", data=data))
                self._channels[topic] = found
            return found

    def topics(self) -> list[str]:
        with self._lock:
            return sorted(self._channels)

    # ------------------------------------------------------------------ the session's side (its reader thread)
    def on_received(self, received: Received) -> None:
        frame, host_ns, _agent_ns, backfilled, _after_end = received
        msg = frame.message
        cls = msg.__class__
        channel = self._rx.get(cls)
        if channel is None:
            channel = self._rx[cls] = self.channel(*message_topic("/agent", cls))
        if channel.has_sinks():  # at --speed max thousands of SAMPLEs a second: encoded only for a subscriber
            channel.log(message_json(msg, frame.seq, frame.flags, backfilled), log_time=host_ns)
        if isinstance(msg, m.ParamValue):
            self._dumps.saw_parameter(msg.name, msg.value)
            self.images.saw_parameter(msg.name, msg.value)
            if self._on_parameter is not None:
                self._on_parameter(msg)
        elif isinstance(msg, m.DumpChunk):
            dump = self._dumps.feed(msg)
            if dump is not None:
                self.publish_dump(dump, host_ns)
        elif isinstance(msg, m.Text) and msg.text == MARKER_CONFIRMATION:
            self.marker_confirmed.set()

    def publish_dump(self, dump: Dump, host_ns: int) -> None:
        self.channel(*dump_topic(dump.kind)).log(body_json(dump.as_dict()), log_time=host_ns)
        self.images.publish(dump, host_ns)

    def on_sent(self, sent: Sent) -> None:
        cls = sent.message.__class__
        channel = self._tx.get(cls)
        if channel is None:
            channel = self._tx[cls] = self.channel(*message_topic("/ground", cls))
        if channel.has_sinks():
            flags = cobs_decode(sent.wire[:-1])[1]  # as the recorder takes them: the frame's flags byte
            channel.log(message_json(sent.message, sent.seq, flags, False), log_time=sent.host_time_ns)

    def on_event(self, event: LinkEvent) -> None:
        topic, schema_name, schema, body = event_topic(event)
        self.channel(topic, schema_name, schema).log(body_json(body), log_time=event.host_time_ns)
