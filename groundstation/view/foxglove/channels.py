"""Every channel of the recording live on a Foxglove server: the recorder's topics, JSON schemas and message bodies."""

from __future__ import annotations

import functools
import json
import threading
from collections.abc import Callable
from typing import Any, TypeVar

import foxglove

from groundstation.links.hub import MARKER_CONFIRMATION
from groundstation.links.hub_events import ACK_ANSWERS
from groundstation.mcap_io import RAW_ENCODING
from groundstation.recording.bodies import body_json, message_json
from groundstation.recording.recorder import dump_topic, event_topic, message_topic
from groundstation.session.dumps import Dump, DumpAssembler
from groundstation.session.events import LinkEvent, Received, Sent
from groundstation.view.foxglove import console
from groundstation.view.foxglove.history import Body, ChannelHistory, FoxgloveHistoryConfig
from groundstation.view.foxglove.images import DumpImages
from protocol import Message
from protocol import messages as m
from protocol.cobs import cobs_decode

MAX_HELD_BACK = 20_000  # live messages of a topic held for one client while its history is sent


class MarkerWatch:
    """A session listener on a run's hub that notes its confirmation of a marker (`mark` service) and its answer to
    an acknowledgement of its alarms (`ack` service)."""

    def __init__(self) -> None:
        self.confirmed = threading.Event()
        self.acknowledged = threading.Event()
        self.ack_answer = ""

    def on_received(self, received: Received) -> None:
        msg = received.frame.message
        if isinstance(msg, m.Text) and msg.text == MARKER_CONFIRMATION:
            self.confirmed.set()
        elif isinstance(msg, m.Text) and msg.text.startswith(ACK_ANSWERS):
            self.ack_answer = msg.text
            self.acknowledged.set()

    def on_sent(self, sent: Sent) -> None:
        pass

    def on_event(self, event: LinkEvent) -> None:
        pass


_Method = TypeVar("_Method", bound=Callable[..., None])
_RAW_SCHEMA = "diving_agent.frame"  # a raw frame: version, flags, seq, id, payload, CRC (protocol/SPEC.md s. 3)


def _publishing(method: _Method) -> _Method:
    """Publishing skipped after it failed once: on a run's own session a listener that raises stops the run (its
    recorder must never stop silently); Foxglove failing must not. The failure is said once, in Foxglove and on
    the run's terminal (`on_failure`)."""

    @functools.wraps(method)
    def guarded(self: FoxgloveChannels, *args: Any) -> None:
        if self.failure is not None:
            return
        try:
            method(self, *args)
        except Exception as e:  # noqa: BLE001 whatever the SDK raises: the run goes on, unpublished
            self.failure = f"Foxglove stopped publishing: {type(e).__name__}: {e}"
            if self._on_failure is not None:
                self._on_failure(self.failure)

    return guarded  # type: ignore[return-value]


class FoxgloveChannels:
    """A session listener: each frame, command and event published on the channel the recording would write it to
    (`/agent/SAMPLE`, `/ground/CMD_PAUSE`, `/link`, `/event`, `/marker`, `/dump/VALUES`), and each completed value
    or policy dump also drawn as an image. A channel is encoded only while a client subscribes to it; what it would
    have carried is kept (bounded: history.py) and sent to each client that subscribes later, to it alone.
    On `dive run` it listens to the run's own session: the very frames, commands and events (alarms) the recorder
    writes."""

    def __init__(self, context: foxglove.Context,
                 on_parameter: Callable[[m.ParamValue], None] | None = None,
                 on_failure: Callable[[str], None] | None = None,
                 history: FoxgloveHistoryConfig | None = None) -> None:
        self._context = context
        self._lock = threading.Lock()  # channels are made from the session's reader thread and from services
        self._channels: dict[str, foxglove.Channel] = {}
        self._rx: dict[type[Message], tuple[foxglove.Channel, str]] = {}  # and its topic
        self._tx: dict[type[Message], tuple[foxglove.Channel, str]] = {}
        self.history = ChannelHistory(history)
        # whom each topic is sent to: clients whose history is sent. Held only to note a message or a client, never
        # while a history is encoded or sent: the publisher (and so the session, once) waited 0.3 s a subscription
        self._publish = threading.Lock()
        self._ready: dict[str, set[int]] = {}
        # (topic, sink) whose history is being sent: the live messages that came meanwhile, sent after it
        self._replaying: dict[tuple[str, int], list[tuple[int, Body]]] = {}
        self.replayed = 0  # messages the last subscribed() sent (its history), for the replay budget (live.py)
        self.held_back_dropped = 0  # live messages past MAX_HELD_BACK while a history was sent: dropped, counted
        self._dumps = DumpAssembler()
        self.images = DumpImages(context, self.sinks)
        self._on_parameter = on_parameter
        self._on_failure = on_failure
        self.failure: str | None = None
        self._times = console.LogTimes()  # the agent's clock, mapped to the host's, as log time (console.py)

    def channel(self, topic: str, schema_name: str, schema: dict[str, Any] | None) -> foxglove.Channel:
        """The channel of `topic`, advertised to clients the first time it is asked for; no `schema`: the raw frames
        (/raw/rx, /raw/tx), in the recording's own encoding, as its MCAP file holds them."""
        with self._lock:
            found = self._channels.get(topic)
            if found is None:
                data = json.dumps(schema).encode() if schema is not None else b""
                found = foxglove.Channel(topic, message_encoding="json" if schema is not None else RAW_ENCODING,
                                         context=self._context, schema=foxglove.Schema(
                                             name=schema_name, encoding="jsonschema" if schema is not None else "",
                                             data=data))
                self._channels[topic] = found
            return found

    def topics(self) -> list[str]:
        with self._lock:
            return sorted(self._channels)

    # ------------------------------------------------------------------ the session's side (its reader thread)
    @_publishing
    def on_received(self, received: Received) -> None:
        frame, host_ns, agent_ns, backfilled, after_end = received
        if after_end:
            return  # from after the run's end: not in the decoded recording either (Session.request_backfill)
        msg = frame.message
        cls = msg.__class__
        found = self._rx.get(cls)
        if found is None:
            topic, schema_name, schema = message_topic("/agent", cls)
            found = self._rx[cls] = (self.channel(topic, schema_name, schema), topic)
        channel, topic = found
        log_ns = self._times.of(topic, host_ns, agent_ns)
        # at --speed max thousands of SAMPLEs a second: encoded only for a subscriber, now or later (history)
        self._send(channel, topic, log_ns, functools.partial(message_json, msg, frame.seq, frame.flags, backfilled))
        self._send(self.channel("/raw/rx", _RAW_SCHEMA, None), "/raw/rx", log_ns,
                   functools.partial(bytes, frame.inner))
        if isinstance(msg, m.Text):
            self._log(functools.partial(console.agent_log, msg, log_ns), log_ns)
        if isinstance(msg, m.ParamValue):
            self._send(self.channel(console.PARAMETER_INFO_TOPIC, console.PARAMETER_INFO_SCHEMA_NAME,
                                    console.PARAMETER_INFO_SCHEMA), console.PARAMETER_INFO_TOPIC, host_ns,
                       functools.partial(console.parameter_info, msg))
            self._dumps.saw_parameter(msg.name, msg.value)
            self.images.saw_parameter(msg.name, msg.value)
            if self._on_parameter is not None:
                self._on_parameter(msg)
        elif isinstance(msg, m.DumpChunk):
            dump = self._dumps.feed(msg)
            if dump is not None:
                self.publish_dump(dump, host_ns)

    def publish_dump(self, dump: Dump, host_ns: int) -> None:
        topic, schema_name, schema = dump_topic(dump.kind)
        body = body_json(dump.as_dict())
        self._send(self.channel(topic, schema_name, schema), topic, host_ns, functools.partial(bytes, body))
        self.images.publish(dump, host_ns)

    @_publishing
    def on_sent(self, sent: Sent) -> None:
        cls = sent.message.__class__
        found = self._tx.get(cls)
        if found is None:
            topic, schema_name, schema = message_topic("/ground", cls)
            found = self._tx[cls] = (self.channel(topic, schema_name, schema), topic)
        channel, topic = found
        inner = cobs_decode(sent.wire[:-1])  # as the recorder takes them: the frame, its flags byte
        self._send(channel, topic, sent.host_time_ns,
                   functools.partial(message_json, sent.message, sent.seq, inner[1], False))
        self._send(self.channel("/raw/tx", _RAW_SCHEMA, None), "/raw/tx", sent.host_time_ns,
                   functools.partial(bytes, inner))

    @_publishing
    def on_event(self, event: LinkEvent) -> None:
        topic, schema_name, schema, body = event_topic(event)
        self._send(self.channel(topic, schema_name, schema), topic, event.host_time_ns,
                   functools.partial(bytes, body_json(body)))
        if event.kind not in console.NOT_LOGGED:
            self._log(functools.partial(console.event_log, event), event.host_time_ns)

    def _log(self, body: Callable[[], bytes | None], log_ns: int) -> None:
        """A line on /log (foxglove.Log), for Foxglove's Log panel."""
        channel = self.channel(console.LOG_TOPIC, console.LOG_SCHEMA_NAME, console.LOG_SCHEMA)
        self._send(channel, console.LOG_TOPIC, log_ns, lambda: body() or b"")

    def _send(self, channel: foxglove.Channel, topic: str, host_ns: int, body: Body) -> None:
        """Kept for later subscribers, and sent to the clients whose replay is done (each to its own sink): never
        broadcast, or a client that just subscribed would get live messages before, and again in, its history."""
        with self._publish:
            self.history.keep(topic, host_ns, body)
            ready = self._ready.get(topic)
            if ready:
                data = body()
                for sink_id in ready:
                    channel.log(data, log_time=host_ns, sink_id=sink_id)
            for (replaying, _), held in self._replaying.items():
                if replaying == topic:
                    if len(held) < MAX_HELD_BACK:
                        held.append((host_ns, body))
                    else:
                        self.held_back_dropped += 1

    def sinks(self, topic: str) -> list[int]:
        """The clients (their sinks) `topic` is sent to now."""
        with self._publish:
            return list(self._ready.get(topic, ()))

    # ------------------------------------------------------------------ a client subscribed (FoxgloveLive's thread)
    @_publishing
    def subscribed(self, topic: str, sink_id: int) -> None:
        """`topic`'s history to the one client whose sink is `sink_id` (the SDK's client id), then its live
        messages: a client that connects late sees the learning curve, the heatmaps and the last minutes whole,
        in order and once. The history is encoded and sent outside the lock (live messages of the topic that come
        meanwhile wait for it, at most MAX_HELD_BACK), each message encoded once for all replays."""
        if self.images.replay(topic, sink_id):  # an image's topic: its newest image, then each new one
            with self._publish:
                self._ready.setdefault(topic, set()).add(sink_id)
            self.replayed = 1
            return
        channel = self._channels.get(topic)
        if channel is None:
            return
        with self._publish:
            kept = self.history.snapshot(topic)  # what a live message after this point is not in
            self._replaying[(topic, sink_id)] = []
        for entry in kept:
            channel.log(entry.encoded(), log_time=entry.host_time_ns, sink_id=sink_id)
        with self._publish:
            held = self._replaying.pop((topic, sink_id), None)
            self.replayed = len(kept)
            if held is None:
                return  # unsubscribed meanwhile
            for host_ns, body in held:
                channel.log(body(), log_time=host_ns, sink_id=sink_id)
            self._ready.setdefault(topic, set()).add(sink_id)

    def unsubscribed(self, topic: str, sink_id: int) -> None:
        with self._publish:
            self._ready.get(topic, set()).discard(sink_id)
            self._replaying.pop((topic, sink_id), None)
