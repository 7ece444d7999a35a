"""`dive log info`: what a recording holds (sessions, duration, episodes, samples, loss, backfill, gaps)."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

from groundstation.mcap_io import RecordingContents, iter_messages
from groundstation.recording.chapters import (
    CHAPTER_TOPICS,
    Chapters,
    ChapterSummary,
    chapter_line,
    chapter_summaries,
    follow_recorded,
)
from groundstation.recording.environments import wire_float32
from groundstation.recording.recorded import Boots, json_fields
from groundstation.session.exactness import SampleIndexCheck
from groundstation.session.gaps import SampleRanges
from protocol import EndReason


@dataclass(frozen=True, slots=True)
class EpisodeSummary:
    episode: int
    outcome: str
    steps: int
    duration_s: float
    episode_return: float
    backfilled: bool
    boot: int = 1
    generation: int = 1  # the learner's chapter in its boot: an episode is keyed (boot, generation, episode)


@dataclass
class BootSummary:
    """One boot of the agent in the recording: its sample indices start at 0 again, so they are counted apart."""

    boot: int
    samples: int = 0
    samples_backfilled: int = 0
    samples_missing: int = 0
    samples_impossible: int = 0  # indices the agent cannot have reached (ignored; see exactness.py)
    first_sample: int | None = None
    end_sample: int | None = None
    boot_id: int | None = None  # the agent's own id of this boot (its HELLO's boot_id), when recorded
    # The sample indices held, as [start, end) ranges: to combine files exactly (summaries.py); not in --json.
    held: list[tuple[int, int]] = field(default_factory=list, repr=False, compare=False)


@dataclass
class RecordingSummary:
    path: str
    complete: bool  # finished with a footer (not cut short)
    sessions: int = 0  # connections (HELLO exchanges) recorded
    link_losses: int = 0
    duration_s: float = 0.0  # host time from the first to the last message recorded
    agent_duration_s: float = 0.0  # agent time spanned by the samples (differs from host time at --speed)
    messages: int = 0
    samples: int = 0
    samples_backfilled: int = 0
    samples_missing: int = 0  # holes in the agent's sample indices that were never filled (all boots)
    frames_lost: int = 0  # by sequence number, from the last link statistics
    rejects: int = 0
    episodes: list[EpisodeSummary] = field(default_factory=list)
    successes: int = 0
    topics: dict[str, int] = field(default_factory=dict)
    agent: dict[str, str] = field(default_factory=dict)
    parameters: dict[str, str] = field(default_factory=dict)
    boots: list[BootSummary] = field(default_factory=list)
    chapters: list[ChapterSummary] = field(default_factory=list)  # per (boot, learner generation)
    malformed: int = 0  # messages whose JSON had the wrong shape (skipped)
    damaged_chunks: int = 0  # chunks skipped because their data was damaged
    part: int = 0  # of a split recording (dive run --split-mb/--split-minutes): 1, 2, ...; 0 = not split

    def as_dict(self) -> dict[str, Any]:
        out = asdict(self)
        for boot in out["boots"]:
            del boot["held"]
        return out


class _Boot:
    def __init__(self, number: int, boot_id: int | None = None) -> None:
        self.summary = BootSummary(number, boot_id=boot_id)
        self.held = SampleRanges()
        self.check = SampleIndexCheck()

    def finish(self) -> BootSummary:
        s = self.summary
        s.samples_missing = sum(b - a for a, b in self.held.missing())
        s.first_sample, s.end_sample = self.held.first, self.held.end
        s.held = self.held.ranges()
        return s


def summarize(path: Path, progress: Callable[[int, int], None] | None = None) -> RecordingSummary:
    """What the recording at `path` holds: through its indexes when it is a finished file (fast, constant memory),
    else (cut short, being written, written by another tool) by reading it as a stream.

    progress(done, total) is called with compressed bytes read as the indexed read goes on.
    """
    from groundstation.mcap_io.indexed import open_indexed
    from groundstation.recording.info_indexed import summarize_indexed

    indexed = open_indexed(path)
    if indexed is None:
        return summarize_stream(path)
    total = indexed.compressed_bytes
    totals = summarize_indexed(indexed, None if progress is None else lambda done: progress(done, total))
    if indexed.indexed_messages != indexed.message_count:  # a message outside the indexes: read every message
        return summarize_stream(path)
    summary = RecordingSummary(str(path), complete=True, sessions=totals.sessions, link_losses=totals.link_losses,
                               messages=totals.messages, frames_lost=totals.frames_lost, rejects=totals.rejects,
                               topics=totals.topics, malformed=totals.malformed, damaged_chunks=totals.damaged_chunks)
    summary.episodes = [_episode(body) for body in totals.episodes]
    summary.chapters = _chapters(totals.chapters, summary.episodes)
    finished = []
    for counts in totals.boots:
        boot = BootSummary(counts.boot, counts.samples, counts.backfilled, counts.held.missing(), counts.impossible,
                           counts.held.first, counts.held.end, counts.boot_id, counts.held.ranges())
        finished.append(boot)
    _finish(summary, finished, totals.first_ns, totals.last_ns, totals.first_us, totals.last_us, indexed.metadata)
    return summary


def summarize_stream(path: Path) -> RecordingSummary:
    """summarize() by reading every message in file order (any file, however damaged or cut short)."""
    info = RecordingContents()
    summary = RecordingSummary(str(path), complete=True)
    boots = Boots()
    chapters = Chapters()
    boot = _Boot(1)
    finished: list[BootSummary] = []
    first_ns = last_ns = None
    first_us = last_us = None
    new_session = True
    for msg in iter_messages(path, None, info):
        if not summary.messages:  # the header is read by now: a split part begins in the boot its header names
            boots.header(info.metadata)
            boot.summary.boot_id = boots.boot_id
        summary.messages += 1
        summary.topics[msg.topic] = summary.topics.get(msg.topic, 0) + 1
        first_ns = msg.log_time_ns if first_ns is None else min(first_ns, msg.log_time_ns)
        last_ns = msg.log_time_ns if last_ns is None else max(last_ns, msg.log_time_ns)
        body: dict[str, Any] | None = {}
        if msg.topic == "/agent/SAMPLE":
            body = json_fields(msg, integers=("sample", "t_us"))
            if body is not None:
                if not boot.check.possible(body["sample"], body["t_us"]):
                    boot.summary.samples_impossible += 1
                    continue
                first_us = body["t_us"] if first_us is None else min(first_us, body["t_us"])
                last_us = body["t_us"] if last_us is None else max(last_us, body["t_us"])
                if boot.held.add(body["sample"]):
                    boot.summary.samples += 1
                    boot.summary.samples_backfilled += bool(body.get("_backfilled"))
        elif msg.topic == "/agent/HEARTBEAT":
            body = json_fields(msg, integers=("log_next_sample", "uptime_ms"))
            if body is not None:
                boot.check.heartbeat(body["log_next_sample"], body["uptime_ms"])
        elif msg.topic == "/agent/EPISODE_END":
            body = json_fields(msg, integers=("episode", "reason", "steps"), numbers=("duration_s", "episode_return"))
            if body is not None:
                summary.episodes.append(_episode(follow_recorded(chapters, boots.current, msg.topic, msg.data)
                                                 or body))
        elif msg.topic in CHAPTER_TOPICS[1:]:  # TEXT, ACK, EPISODE_START: where a chapter begins
            body = follow_recorded(chapters, boots.current, msg.topic, msg.data)
        elif msg.topic == "/agent/HELLO":
            # The agent's HELLO on connect and its answer to ours are one session: the first after a start or a loss.
            if new_session:
                summary.sessions += 1
                new_session = False
            if boots.hello(msg):
                finished.append(boot.finish())
                boot = _Boot(boots.current, boots.boot_id)
            boot.summary.boot_id = boots.boot_id  # the first HELLO of a file without a header names boot 1
            follow_recorded(chapters, boots.current, msg.topic, msg.data)
        elif msg.topic == "/event":
            body = json_fields(msg)
            if body is not None and body.get("kind") == "link_lost":
                summary.link_losses += 1
                new_session = True
        elif msg.topic == "/link":
            body = json_fields(msg)
            link = body.get("link") if body is not None else None
            if isinstance(link, dict):
                summary.frames_lost = _count(link.get("rx_lost"))
                summary.rejects = _count(link.get("rx_rejects"))
        if body is None:
            summary.malformed += 1
    finished.append(boot.finish())
    summary.chapters = _chapters(chapters, summary.episodes)
    summary.complete = not info.truncated
    summary.damaged_chunks = info.damaged_chunks
    _finish(summary, finished, first_ns, last_ns, first_us, last_us, info.metadata)
    return summary


def _episode(body: dict[str, Any]) -> EpisodeSummary:
    reason = body["reason"]
    outcome = EndReason(reason).name.lower() if reason in (1, 2, 3) else str(reason)
    # the wire's float32 at its precision (2.8): as a recording holds it now, or widened by an older recorder
    return EpisodeSummary(body["episode"], outcome, body["steps"], wire_float32(body["duration_s"] or 0.0),
                          wire_float32(body["episode_return"] or 0.0), bool(body.get("_backfilled")),
                          int(body.get("boot", 1)), int(body.get("generation", 1)))


def _chapters(chapters: Chapters, episodes: list[EpisodeSummary]) -> list[ChapterSummary]:
    return chapter_summaries(chapters.restarts, [(e.boot, e.generation, e.outcome) for e in episodes])


def _finish(summary: RecordingSummary, finished: list[BootSummary], first_ns: int | None, last_ns: int | None,
            first_us: int | None, last_us: int | None, metadata: dict[str, list[dict[str, str]]]) -> None:
    """What both readers derive alike: totals over boots, durations, episodes in order, header fields."""
    summary.boots = [b for b in finished if b.samples or b.samples_impossible or len(finished) == 1]
    summary.episodes.sort(key=lambda e: (e.boot, e.generation, e.episode))
    summary.successes = sum(e.outcome == "success" for e in summary.episodes)
    summary.samples = sum(b.samples for b in finished)
    summary.samples_backfilled = sum(b.samples_backfilled for b in finished)
    summary.samples_missing = sum(b.samples_missing for b in finished)
    summary.duration_s = (last_ns - first_ns) / 1e9 if first_ns is not None and last_ns is not None else 0.0
    if first_us is not None and last_us is not None:
        summary.agent_duration_s = (last_us - first_us) / 1e6
    session = (metadata.get("session") or [{}])[0]
    if session.get("split") == "true" and session.get("part", "").isdigit():
        summary.part = int(session["part"])
    for name, key in (("agent_hello", "agent"), ("parameters", "parameters")):
        if metadata.get(name):
            setattr(summary, key, metadata[name][-1])


def _count(value: object) -> int:
    return value if isinstance(value, int) and not isinstance(value, bool) else 0


def format_summary(s: RecordingSummary) -> str:
    agent = s.agent.get("name", "?")
    node_id = s.agent.get("node_id", "?")
    node_id = f"{int(node_id):08x}" if node_id.isdigit() else node_id  # in hex, as dive status and file names
    # A later part of a split recording holds no HELLO of its own: its session began in an earlier part.
    sessions = f"part {s.part} of a split recording" + (f", {s.sessions} session(s)" if s.sessions else "") \
        if s.part > 1 else f"{s.sessions} session(s)"
    lines = [
        f"{s.path}{'' if s.complete else '  (truncated: run `dive log recover`)'}",
        f"  agent {agent} id {node_id}, {sessions}, {s.link_losses} link loss(es), "
        f"{s.duration_s:.1f} s host time ({s.agent_duration_s:.1f} s agent time), {s.messages} messages",
        f"  samples {s.samples} ({s.samples_backfilled} backfilled, {s.samples_missing} still missing), "
        f"frames lost {s.frames_lost}, rejects {s.rejects}",
        f"  episodes {len(s.episodes)} ({s.successes} successes)",
    ]
    if len(s.boots) > 1:  # sample indices restart at a reboot: each boot's holes are its own
        for b in s.boots:
            lines.append(f"    boot {b.boot}: samples {b.samples} [{b.first_sample}, {b.end_sample}) "
                         f"({b.samples_backfilled} backfilled, {b.samples_missing} still missing)")
    impossible = sum(b.samples_impossible for b in s.boots)
    for count, what in ((impossible, "SAMPLE indices the agent cannot have reached (ignored)"),
                        (s.malformed, "messages of the wrong shape (skipped)"),
                        (s.damaged_chunks, "damaged chunks (skipped; the rest was read)")):
        if count:
            lines.append(f"  {count} {what}")
    # Episode numbers restart with a learner (and a boot): each chapter's figures are its own, and its episodes
    # follow a line that says where the learner restarted.
    chaptered = len(s.chapters) > 1 or any(c.why for c in s.chapters)
    if chaptered:
        lines.extend(f"    {chapter_line(n, c)}" for n, c in enumerate(s.chapters, 1))
    chapter = (1, 1) if chaptered else None
    for e in s.episodes:
        if chapter is not None and (e.boot, e.generation) != chapter:
            chapter = (e.boot, e.generation)
            number, heading = next((n, c) for n, c in enumerate(s.chapters, 1) if (c.boot, c.generation) == chapter)
            lines.append(f"  -- {chapter_line(number, heading)}")
        lines.append(f"    {e.episode:5d}  {e.outcome:8s} {e.steps:6d} steps  {e.duration_s:8.1f} s  "
                     f"return {e.episode_return:9.1f}{'  (backfilled)' if e.backfilled else ''}")
    return "\n".join(lines)
