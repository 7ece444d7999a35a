"""Recordings as data: `open_recording(path, ...)` gives per-topic numpy tables, episodes and time windows.

    from groundstation import open_recording
    rec = open_recording("recordings/run.mcap")          # or several files / a folder of split parts
    samples = rec.samples()                              # numpy structured array, one row per sample
    rec.episodes()                                       # one row per episode, with its boot
    rec.table("/agent/HEARTBEAT")                        # any JSON topic
    rec.dataframe("/agent/SAMPLE")                       # the same as a pandas DataFrame (pandas optional)
    for msg in rec.messages({"/agent/TEXT"}, start_s=10, end_s=20): ...   # a window of agent time

Every row carries `host_time_ns` (when the ground station received it) and, for agent messages, the
agent's own `t_us`. A recording that spans an agent reboot is told apart by `boot` (1, 2, ... in file
order, from the agents' HELLOs as `dive log info` counts them; `boot_ids` gives each one's boot id):
sample and episode numbers restart with a boot. Agent messages also carry `generation`, the learner's
chapter within its boot (chapters.py): episode numbers restart with a learner restart too, so an episode is
keyed by (boot, generation, episode); `restarts` says where each chapter began and whether it was inferred.
Samples received twice (live and backfilled) appear once; messages whose JSON has the wrong shape are
counted in `malformed` and left out. The ground's own records (/link, /event, ...) nest objects: their fields
are columns named by path (`link_rtt_median_ms`, `data_alarm`).
"""

from __future__ import annotations

from collections.abc import Iterable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from groundstation.errors import RecordingError
from groundstation.mcap_io import RecordedMessage, RecordingContents, iter_messages
from groundstation.recording.chapters import Chapters, Restart
from groundstation.recording.recorded import Boots, header_boot_id, json_fields
from protocol import EndReason

SAMPLE_TOPIC = "/agent/SAMPLE"
HELLO_TOPIC = "/agent/HELLO"
EPISODE_START_TOPIC = "/agent/EPISODE_START"
EPISODE_END_TOPIC = "/agent/EPISODE_END"
_TIME_FIELDS = ("boot", "host_time_ns")
_OUTCOMES = {int(r): r.name.lower() for r in EndReason}
# Fields the tables index by: a message without them as integers is malformed (recordings are untrusted input).
_REQUIRED_INTEGERS: dict[str, tuple[str, ...]] = {
    SAMPLE_TOPIC: ("t_us", "sample", "episode", "step", "state", "action", "mode"),
    EPISODE_START_TOPIC: ("t_us", "episode", "sample"),
    EPISODE_END_TOPIC: ("t_us", "episode", "sample", "reason", "steps"),
}


def recording_files(paths: Iterable[str | Path]) -> list[Path]:
    """The MCAP files named, a folder standing for the .mcap files in it, in name order (split parts sort)."""
    files: list[Path] = []
    for raw in paths:
        path = Path(raw)
        if path.is_dir():
            found = sorted(path.glob("*.mcap"))
            if not found:
                raise RecordingError(f"{path} holds no .mcap recordings")
            files.extend(found)
        else:
            files.append(path)
    if not files:
        raise RecordingError("no recording given")
    return files


@dataclass
class _Rows:
    """Decoded JSON rows of one topic, with the columns every row gets."""

    rows: list[dict[str, Any]] = field(default_factory=list)


class Recording:
    """One or more MCAP files of the same session(s), read once into per-topic rows."""

    def __init__(self, files: list[Path]) -> None:
        self.files = files
        self.contents: list[RecordingContents] = []
        self._topics: dict[str, _Rows] = {}
        self._raw: list[tuple[str, int, int, int, RecordedMessage]] = []  # topic, boot, host ns, agent us, msg
        self.boot_ids: dict[int, int] = {}  # boot number -> the agent's boot_id
        self.malformed = 0  # JSON messages of the wrong shape, left out of the tables
        self.restarts: list[Restart] = []  # the learner restarts, in file order (a new chapter each)
        self._read()

    # ------------------------------------------------------------------ reading
    def _read(self) -> None:
        boots = Boots()
        chapters = Chapters()
        seen_samples: set[tuple[int, int]] = set()
        for path in self.files:
            info = RecordingContents()
            first = True
            for msg in iter_messages(path, None, info):
                if first:  # the header is read: a split part (no HELLO of its own) begins in the boot it names
                    first = False
                    if boots.header(info.metadata) or not self.boot_ids:
                        boot_id = header_boot_id(info.metadata)
                        if boot_id is not None:
                            self.boot_ids.setdefault(boots.current, boot_id)
                body = json_fields(msg, _REQUIRED_INTEGERS.get(msg.topic, ())) if msg.encoding == "json" else None
                if msg.topic == HELLO_TOPIC:
                    boots.hello(msg)
                    if body is not None and isinstance(body.get("boot_id"), int):
                        self.boot_ids.setdefault(boots.current, body["boot_id"])
                boot = boots.current
                t_us = body.get("t_us", -1) if body is not None else -1
                t_us = t_us if isinstance(t_us, int) and not isinstance(t_us, bool) else -1
                self._raw.append((msg.topic, boot, msg.log_time_ns, t_us, msg))
                if body is None:
                    self.malformed += msg.encoding == "json"
                    continue
                if msg.topic == SAMPLE_TOPIC:
                    key = (boot, int(body.get("sample", -1)))
                    if key in seen_samples:
                        continue  # received live and again backfilled, or twice: one row
                    seen_samples.add(key)
                if not msg.topic.startswith("/agent/"):  # the agent's messages are flat; the ground's records nest
                    body = _flat(body)
                body["boot"], body["host_time_ns"] = boot, msg.log_time_ns
                if msg.topic.startswith("/agent/"):
                    body["generation"] = chapters.follow(boot, msg.topic, body)
                self._topics.setdefault(msg.topic, _Rows()).rows.append(body)
            self.contents.append(info)
        self.restarts = chapters.restarts
        by_index = chapters.sample_generations()
        for row in self._rows(SAMPLE_TOPIC):  # by index, not arrival: a backfilled sample arrives after a restart
            row["generation"] = by_index.generation(row["boot"], int(row["sample"]))

    # ------------------------------------------------------------------ what it holds
    @property
    def truncated(self) -> bool:
        """True if any file ended early (a crash): what was read up to there is here."""
        return any(c.truncated for c in self.contents)

    @property
    def topics(self) -> dict[str, int]:
        """Message count per topic (every topic, JSON or not)."""
        counts: dict[str, int] = {}
        for topic, *_ in self._raw:
            counts[topic] = counts.get(topic, 0) + 1
        return counts

    @property
    def boots(self) -> list[int]:
        """The boot numbers that hold messages, in file order (1, 2, ...: one more per agent reboot)."""
        return sorted({boot for _, boot, _, _, _ in self._raw})

    @property
    def metadata(self) -> dict[str, list[dict[str, str]]]:
        merged: dict[str, list[dict[str, str]]] = {}
        for info in self.contents:
            for name, entries in info.metadata.items():
                merged.setdefault(name, []).extend(entries)
        return merged

    @property
    def agent(self) -> dict[str, str]:
        """The agent's identity as the newest HELLO recorded it (name, node_id, boot_id, versions)."""
        entries = self.metadata.get("agent_hello", [])
        return entries[-1] if entries else {}

    @property
    def parameters(self) -> dict[str, str]:
        entries = self.metadata.get("parameters", [])
        return entries[-1] if entries else {}

    # ------------------------------------------------------------------ tables
    def table(self, topic: str) -> NDArray[np.void]:
        """Every JSON message of `topic` as a structured array; columns are the message's fields plus
        `boot` and `host_time_ns`. Nested objects are columns by path; lists are left out (messages() has them)."""
        rows = self._topics.get(topic)
        if rows is None:
            if topic not in self.topics:
                raise RecordingError(f"the recording has no topic {topic}; it has {', '.join(sorted(self.topics))}")
            return np.zeros(0, dtype=[(name, "<i8") for name in _TIME_FIELDS])
        return _structured(rows.rows)

    def samples(self) -> NDArray[np.void]:
        """SAMPLEs, one row per (boot, sample index), in boot then sample order, each with its `generation`."""
        table = self.table(SAMPLE_TOPIC)
        if len(table) == 0:
            return table
        return table[np.lexsort((table["sample"], table["boot"]))]

    def episodes(self) -> NDArray[np.void]:
        """One row per episode, keyed (boot, generation, episode): outcome, start/end sample and agent time, steps,
        return."""
        starts = {episode_key(r): r for r in self._rows(EPISODE_START_TOPIC)}
        ends = {episode_key(r): r for r in self._rows(EPISODE_END_TOPIC)}
        dtype = [("boot", "<i8"), ("generation", "<i8"), ("episode", "<i8"), ("outcome", "<U8"),
                 ("first_sample", "<i8"), ("last_sample", "<i8"), ("start_t_us", "<i8"), ("end_t_us", "<i8"),
                 ("steps", "<i8"), ("duration_s", "<f8"), ("episode_return", "<f8"), ("backfilled", "?")]
        keys = sorted(set(starts) | set(ends))
        out = np.zeros(len(keys), dtype=dtype)
        for i, key in enumerate(keys):
            start, end = starts.get(key, {}), ends.get(key, {})
            out[i] = (
                key[0], key[1], key[2], _OUTCOMES.get(int(end.get("reason", 0)), "open" if not end else "?"),
                start.get("sample", -1), end.get("sample", -1), start.get("t_us", -1), end.get("t_us", -1),
                end.get("steps", 0), end.get("duration_s", np.nan), end.get("episode_return", np.nan),
                bool(start.get("_backfilled") or end.get("_backfilled")),
            )
        return out

    def dataframe(self, topic: str = SAMPLE_TOPIC) -> Any:
        """table(topic) (samples() for SAMPLE) as a pandas DataFrame; needs pandas installed."""
        try:
            import pandas as pd
        except ImportError as e:
            raise RecordingError("dataframe() needs pandas: pip install pandas (or use table(), numpy only)") from e
        return pd.DataFrame(self.samples() if topic == SAMPLE_TOPIC else self.table(topic))

    def messages(
        self, topics: set[str] | None = None, start_s: float | None = None, end_s: float | None = None,
        clock: str = "agent",
    ) -> Iterator[RecordedMessage]:
        """Messages in recorded order whose time lies in [start_s, end_s): seconds of agent time from the
        first SAMPLE (`clock="agent"`, messages without agent time are left out of a window) or of host
        time from the first message (`clock="host"`)."""
        if clock not in ("agent", "host"):
            raise RecordingError(f"clock must be 'agent' or 'host', not {clock!r}")
        windowed = start_s is not None or end_s is not None
        origin = self._origin(clock)
        for topic, _boot, host_ns, agent_us, msg in self._raw:
            if topics is not None and topic not in topics:
                continue
            if windowed:
                if clock == "agent" and agent_us < 0:
                    continue
                t = (agent_us - origin) / 1e6 if clock == "agent" else (host_ns - origin) / 1e9
                if (start_s is not None and t < start_s) or (end_s is not None and t >= end_s):
                    continue
            yield msg

    def _origin(self, clock: str) -> int:
        if clock == "host":
            return min((host_ns for _, _, host_ns, _, _ in self._raw), default=0)
        samples = self._topics.get(SAMPLE_TOPIC)
        return min((int(r["t_us"]) for r in samples.rows), default=0) if samples else 0

    def _rows(self, topic: str) -> list[dict[str, Any]]:
        rows = self._topics.get(topic)
        return rows.rows if rows else []


def episode_key(row: dict[str, Any]) -> tuple[int, int, int]:
    """An episode's key in every data path: (boot, generation, episode)."""
    return int(row["boot"]), int(row.get("generation", 1)), int(row["episode"])


def open_recording(*paths: str | Path) -> Recording:
    """Read one or more recordings (files, or folders of .mcap files) of a session into a Recording."""
    return Recording(recording_files(paths))


def _flat(body: dict[str, Any], prefix: str = "") -> dict[str, Any]:
    """Nested objects as columns named by their path: {"link": {"rtt_median_ms": 3}} -> link_rtt_median_ms."""
    flat: dict[str, Any] = {}
    for key, value in body.items():
        if isinstance(value, dict):
            flat.update(_flat(value, f"{prefix}{key}_"))
        else:
            flat[f"{prefix}{key}"] = value
    return flat


def _structured(rows: list[dict[str, Any]]) -> NDArray[np.void]:
    """Rows of JSON objects as a structured array: ints as int64, floats as float64, bools, strings."""
    columns: dict[str, str] = {}
    for row in rows:
        for key, value in row.items():
            kind = _kind(value)
            if kind is None:
                continue
            known = columns.get(key)
            if known is None or (known == "<i8" and kind == "<f8"):
                columns[key] = kind
            elif known != kind and not (known == "<f8" and kind == "<i8"):
                columns[key] = "O"
    names = list(columns)
    out = np.zeros(len(rows), dtype=[(name, columns[name]) for name in names])
    for name in names:
        kind = columns[name]
        missing: Any = np.nan if kind == "<f8" else -1 if kind == "<i8" else False if kind == "?" else ""
        out[name] = [row.get(name, missing) for row in rows]
    return out


def _kind(value: Any) -> str | None:
    if isinstance(value, bool):
        return "?"
    if isinstance(value, int):
        return "<i8"
    if isinstance(value, float):
        return "<f8"
    if isinstance(value, str):
        return "O"
    return None
