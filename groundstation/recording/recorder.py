"""The MCAP recorder: a session listener writing every frame, command, event, dump and marker (TEAM.md format)."""

from __future__ import annotations

import functools
import os
import platform
import socket
import sys
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any, TypeVar

from groundstation.errors import RecordingError, RecordingExistsError
from groundstation.mcap_io import RAW_ENCODING, McapFileWriter, mcap_library_version
from groundstation.recording.bodies import body_json, compact_json, message_json
from groundstation.recording.held_frames import EarlyFrames, UnusedFrames
from groundstation.recording.safe_files import unused_name
from groundstation.session.dumps import DumpAssembler
from groundstation.session.events import EventKind, LinkEvent, Received, Sent
from groundstation.session.hello import tool_version
from protocol import DumpKind, Message, messages
from protocol.cobs import cobs_decode
from protocol.jsonschema import message_json_schema

ENVELOPE = {
    "_seq": {"type": "integer", "description": "frame sequence number", "minimum": 0, "maximum": 65535},
    "_flags": {"type": "integer", "description": "frame flags (FrameFlag)", "minimum": 0, "maximum": 255},
    "_backfilled": {"type": "boolean", "description": "re-sent from the agent's on-board log after an outage"},
}
_OBJECT = {"$schema": "https://json-schema.org/draft/2020-12/schema", "type": "object"}
LINK_SCHEMA = {**_OBJECT, "title": "link statistics (1 Hz)", "properties": {
    "link": {"type": "object", "description": "frames, bytes, loss, rejects by cause; rtt_*_ms in ms"},
    "clock": {"type": "object", "description": "clock model: offset_us [us], drift_ppm [ppm]"}}}
EVENT_SCHEMA = {**_OBJECT, "title": "link event", "required": ["kind", "detail"], "properties": {
    "kind": {"type": "string"}, "detail": {"type": "string"}, "data": {"type": "object"}}}
MARKER_SCHEMA = {**_OBJECT, "title": "user marker", "required": ["text"], "properties": {"text": {"type": "string"}}}
DUMP_SCHEMA = {**_OBJECT, "title": "reassembled dump", "required": ["dump_id", "episode", "kind", "values"],
               "properties": {"dump_id": {"type": "integer"}, "episode": {"type": "integer"},
                              "kind": {"type": "string"},
                              "values": {"type": "array", "description": "state-major array (SPEC.md section 10)"}}}


def message_schema(message_type: type[Message]) -> dict[str, Any]:
    """The channel schema: the message's JSON Schema (units included) plus the frame envelope."""
    schema = message_json_schema(message_type.DEFINITION)
    schema["properties"] = {**schema["properties"], **ENVELOPE}
    return schema


def message_topic(prefix: str, message_type: type[Message]) -> tuple[str, str, dict[str, Any]]:
    """A message's channel: topic (prefix /agent for received, /ground for sent), schema name and JSON schema."""
    name = message_type.DEFINITION.name
    return f"{prefix}/{name}", f"diving_agent.{name}", message_schema(message_type)


def dump_topic(kind: DumpKind) -> tuple[str, str, dict[str, Any]]:
    """A reassembled dump's channel: topic, schema name and JSON schema."""
    return f"/dump/{kind.name}", "diving_agent.dump", DUMP_SCHEMA


def event_topic(event: LinkEvent) -> tuple[str, str, dict[str, Any], Any]:
    """An event's channel (link statistics, a marker, any other event): topic, schema name, schema, and body."""
    if event.kind == EventKind.STATS:
        return "/link", "diving_agent.link", LINK_SCHEMA, event.data
    if event.kind == EventKind.MARKER:
        return "/marker", "diving_agent.marker", MARKER_SCHEMA, {"text": event.detail}
    return "/event", "diving_agent.event", EVENT_SCHEMA, {"kind": str(event.kind), "detail": event.detail,
                                                          "data": event.data}


_NOTED = frozenset((messages.ParamValue, messages.DumpChunk, messages.Hello))  # see Recorder._note


@dataclass(frozen=True, slots=True)
class RecorderConfig:
    directory: Path = Path("recordings")
    path: Path | None = None  # an exact file name instead of one made from time and agent id
    split_bytes: int = 0  # 0 = never split
    split_s: float = 0.0
    flush_period_s: float = 1.0

    @property
    def splits(self) -> bool:
        return bool(self.split_bytes or self.split_s)

    @property
    def first_file(self) -> Path | None:
        """The first file's name when the user gave one: `path`, or `path`'s stem + `-part001.mcap` when splitting."""
        if self.path is None or not self.splits:
            return self.path
        return self.path.with_name(f"{self.path.stem}-part001.mcap")


_SIZE_CHECK_FRAMES = 32  # frames between looks at a split part's size on disk (~2 KB of disk at most between)

_Method = TypeVar("_Method", bound=Callable[..., None])


def _guarded(method: _Method) -> _Method:
    """A recorder method under its lock, skipped after a failed write, turning a new failure into `failure`."""

    @functools.wraps(method)
    def guarded(self: Recorder, *args: Any) -> None:
        with self._lock:
            if self.failure is not None:
                return
            try:
                method(self, *args)
            except OSError as e:  # RecordingError is an OSError too
                self._fail(e)

    return guarded  # type: ignore[return-value]


class Recorder:
    """Opens its file at the agent's first HELLO (the name holds the agent id); thread-safe."""

    def __init__(self, config: RecorderConfig | None = None, session_info: dict[str, Any] | None = None) -> None:
        self.config = config or RecorderConfig()
        self.session_info = session_info or {}
        self.paths: list[Path] = []
        self._writer: McapFileWriter | None = None
        self._opened_s = 0.0
        self._lock = threading.Lock()
        self._early = EarlyFrames()
        self._agent_id = 0
        self._stamp = time.strftime("%Y%m%d-%H%M%S")
        self._hello: dict[str, Any] = {}
        self._parameters: dict[str, Any] = {}
        self._dumps = DumpAssembler()
        # Channel ids of the open file by message class (received, sent) and of /raw/rx: looked up per frame.
        self._rx_channels: dict[type[Message], int] = {}
        self._tx_channels: dict[type[Message], int] = {}
        self._raw_rx = 0
        self._unused: UnusedFrames | None = None  # /raw/rx_unused of the open part
        self._splits = self.config.splits
        self._base: Path | None = None  # the file name without its part number and suffix, fixed at the first file
        # Every part's session metadata carries it: readers tell the parts of one recording from other recordings.
        self._recording_id = os.urandom(8).hex()
        self._part_frames = 0  # frames received since the last look at the file's size (see _rotate_if_due)
        self.failure: RecordingError | None = None  # the first write that failed; nothing is written after it

    @property
    def path(self) -> Path | None:
        return self.paths[-1] if self.paths else None

    # ------------------------------------------------------------------ listener
    def on_received(self, received: Received) -> None:
        # _guarded written out: this runs for every frame, and the decorator's extra call is a tenth of its cost.
        with self._lock:
            if self.failure is not None:
                return
            try:
                if self._writer is None or self._splits:
                    self._first_or_rotate(received)
                    if self._writer is None:
                        return
                self._write_received(received)
            except OSError as e:  # RecordingError is an OSError too
                self._fail(e)

    def _first_or_rotate(self, received: Received) -> None:
        """Open the file at the agent's HELLO (keeping what came before it), or start the next part when due."""
        msg = received.frame.message
        if self._writer is None and isinstance(msg, messages.Hello):
            self._hello = msg.to_dict()
            self._agent_id = msg.node_id
            self._open()
        if self._writer is None:
            self._early.keep(self._write_received, received)
        elif self._splits:
            self._rotate_if_due()

    @_guarded
    def on_unused(self, received: Received) -> None:
        """A frame the session received but did not use: raw, on /raw/rx_unused (held_frames.UnusedFrames)."""
        if self._writer is None:
            self._early.keep(self._write_unused, received)
            return
        self._write_unused(received)

    def _write_unused(self, received: Received) -> None:
        assert self._unused is not None
        self._unused.write(received)

    @_guarded
    def on_sent(self, sent: Sent) -> None:
        if self._writer is None:
            self._early.keep(self._write_sent, sent)
            return
        self._write_sent(sent)

    @_guarded
    def on_event(self, event: LinkEvent) -> None:
        if self._writer is None:
            self._early.keep(self._write_event, event)
            return
        self._write_event(event)

    @_guarded
    def set_parameters(self, values: dict[str, Any]) -> None:
        self._parameters = dict(values)
        if self._writer is not None:
            self._writer.metadata("parameters", self._parameters)

    @_guarded
    def close(self) -> None:
        if self._writer is not None:
            writer, self._writer = self._writer, None
            writer.close()

    def _fail(self, error: OSError) -> None:
        """Record nothing more after a failed write (disk full, folder not writable), keep what was written
        readable, and keep the error for the run to report; the session goes on and closes the link cleanly."""
        where = self.path or self.config.directory
        self.failure = error if isinstance(error, RecordingError) else RecordingError(
            f"cannot write the recording {where}: {error.strerror or error}")
        writer, self._writer = self._writer, None
        if writer is not None:
            try:
                writer.close()
            except OSError:
                pass  # the footer may not fit on a full disk; the chunks already flushed stay readable

    # ------------------------------------------------------------------ internals
    def _file_name(self, base: Path) -> Path:
        """`base.mcap`, or for split parts `base-part001.mcap`, `base-part002.mcap`, ...: zero-padded, so name order
        (ls, a glob, a folder given to `dive replay`) is time order."""
        part = f"-part{len(self.paths) + 1:03d}" if self._splits else ""
        return base.with_name(f"{base.name}{part}.mcap")

    def _create(self) -> McapFileWriter:
        """The next file: the name the user gave (refused if it exists), else a made-up name no file has yet.

        The parts of one recording share one base name: when `…-part001.mcap` is taken (two recorders of one agent in
        the same second, say the run and a `dive record` through its hub), this one becomes `…-2-part001.mcap`, and its
        later parts `…-2-part002.mcap`, never mixed into the other's.
        """
        if self._base is None:
            self._base = self.config.path.with_suffix("") if self.config.path else \
                self.config.directory / f"{self._stamp}-agent{self._agent_id:08x}"
        if self.config.path is not None and not self.paths:
            return McapFileWriter(self._file_name(self._base), self.config.flush_period_s)
        stem, number = self._base, 1
        while True:
            path = self._file_name(self._base)
            if not self.paths and path.exists():
                number += 1
                self._base = stem.with_name(f"{stem.name}-{number}")
                continue
            try:  # a later part's name taken all the same (a copy put there): the next free name
                return McapFileWriter(unused_name(path) if self.paths else path, self.config.flush_period_s)
            except RecordingExistsError:
                continue  # taken between the look and the exclusive create

    def _open(self) -> None:
        self._writer = self._create()
        path = self._writer.path
        self._rx_channels, self._tx_channels = {}, {}
        self._raw_rx = self._writer.channel("/raw/rx", RAW_ENCODING)
        self._unused = UnusedFrames(self._writer)
        self.paths.append(path)
        self._opened_s = time.monotonic()
        w = self._writer
        w.metadata("agent_hello", self._hello)
        w.metadata("host", {"hostname": socket.gethostname(), "platform": platform.platform(),
                            "python": sys.version.split()[0], "dive": tool_version(),
                            "mcap": mcap_library_version()})
        # The session header every part carries, so that each opens on its own (dive log info, replay, export):
        # the agent's HELLO, the host, the session with the part number and recording id, the parameter table.
        w.metadata("session", {**self.session_info, "part": str(len(self.paths)),
                               "split": "true" if self._splits else "false", "recording_id": self._recording_id,
                               "started_ns": str(time.time_ns())})
        if self._parameters:
            w.metadata("parameters", self._parameters)
        self._early.write_all()
        w.flush()  # header, metadata and the first frames on disk now, not after the first second

    def _rotate_if_due(self) -> None:
        w = self._writer
        assert w is not None
        self._part_frames += 1
        if self._part_frames < _SIZE_CHECK_FRAMES:  # the size on disk is an estimate; no need to look every frame
            return
        self._part_frames = 0
        too_big = self.config.split_bytes and w.size_on_disk() >= self.config.split_bytes
        too_old = self.config.split_s and time.monotonic() - self._opened_s >= self.config.split_s
        if too_big or too_old:
            w.close()
            self._open()

    def _write_received(self, received: Received) -> None:
        w = self._writer
        assert w is not None
        frame, host_ns, agent_ns, backfilled, after_end = received
        if after_end:  # from after the run's end: the raw frame only (Session.request_backfill)
            w.write(self._raw_rx, frame.inner, host_ns, agent_ns)
            return
        msg = frame.message
        cls = msg.__class__
        channel = self._rx_channels.get(cls)
        if channel is None:
            channel = self._rx_channels[cls] = self._message_channel(w, "/agent", cls)
        w.write_frame(channel, message_json(msg, frame.seq, frame.flags, backfilled), self._raw_rx, frame.inner,
                      host_ns, agent_ns)
        if cls in _NOTED:
            self._note(msg, host_ns)

    def _note(self, msg: Message, host_ns: int) -> None:
        """What the recorder keeps of a few messages: a parameter (it bounds a dump's size, and the next part's
        header carries the table), a dump's chunks (the last one completes it: the dump goes to /dump/<kind>),
        a HELLO (the next part's header names the agent's boot)."""
        w = self._writer
        assert w is not None
        if isinstance(msg, messages.ParamValue):
            self._dumps.saw_parameter(msg.name, msg.value)
            if self._parameters:  # the table the next part's header carries stays current (a tool's `params set`)
                self._parameters[msg.name] = msg.value
        elif isinstance(msg, messages.DumpChunk):
            dump = self._dumps.feed(msg)
            if dump is not None:
                body = compact_json(dump.as_dict()).encode()
                topic, schema_name, schema = dump_topic(dump.kind)
                w.write(w.channel(topic, "json", schema_name, schema), body, host_ns)
        elif isinstance(msg, messages.Hello):  # after a reboot the next part's header names the new boot
            self._hello = msg.to_dict()

    def _write_sent(self, sent: Sent) -> None:
        w = self._writer
        assert w is not None
        inner = cobs_decode(sent.wire[:-1])
        cls = sent.message.__class__
        channel = self._tx_channels.get(cls)
        if channel is None:
            channel = self._tx_channels[cls] = self._message_channel(w, "/ground", cls)
        w.write(channel, message_json(sent.message, sent.seq, inner[1], False), sent.host_time_ns)
        w.write(w.channel("/raw/tx", RAW_ENCODING), inner, sent.host_time_ns)

    @staticmethod
    def _message_channel(w: McapFileWriter, prefix: str, cls: type[Message]) -> int:
        topic, schema_name, schema = message_topic(prefix, cls)
        return w.channel(topic, "json", schema_name, schema)

    def _write_event(self, event: LinkEvent) -> None:
        w = self._writer
        assert w is not None
        topic, schema_name, schema, body = event_topic(event)
        w.write(w.channel(topic, "json", schema_name, schema), body_json(body), event.host_time_ns)

