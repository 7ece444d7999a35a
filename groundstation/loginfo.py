"""`dive log info`: what a recording holds (sessions, duration, episodes, samples, loss, backfill, gaps)."""

from __future__ import annotations

from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

from groundstation.gaps import SampleRanges
from groundstation.mcap_io import RecordingContents, iter_messages
from protocol import EndReason


@dataclass(frozen=True, slots=True)
class EpisodeSummary:
    episode: int
    outcome: str
    steps: int
    duration_s: float
    episode_return: float
    backfilled: bool


@dataclass
class RecordingSummary:
    path: str
    complete: bool  # finished with a footer (not cut short)
    sessions: int = 0  # connections (HELLO exchanges) recorded
    link_losses: int = 0
    duration_s: float = 0.0
    messages: int = 0
    samples: int = 0
    samples_backfilled: int = 0
    samples_missing: int = 0  # holes in the agent's sample indices that were never filled
    frames_lost: int = 0  # by sequence number, from the last link statistics
    rejects: int = 0
    episodes: list[EpisodeSummary] = field(default_factory=list)
    successes: int = 0
    topics: dict[str, int] = field(default_factory=dict)
    agent: dict[str, str] = field(default_factory=dict)
    parameters: dict[str, str] = field(default_factory=dict)

    def as_dict(self) -> dict[str, Any]:
        return asdict(self)


def summarize(path: Path) -> RecordingSummary:
    info = RecordingContents()
    summary = RecordingSummary(str(path), complete=True)
    held = SampleRanges()
    first_ns = last_ns = None
    for msg in iter_messages(path, None, info):
        summary.messages += 1
        summary.topics[msg.topic] = summary.topics.get(msg.topic, 0) + 1
        first_ns = msg.log_time_ns if first_ns is None else min(first_ns, msg.log_time_ns)
        last_ns = msg.log_time_ns if last_ns is None else max(last_ns, msg.log_time_ns)
        if msg.topic == "/agent/SAMPLE":
            body = msg.json()
            if held.add(body["sample"]):
                summary.samples += 1
                summary.samples_backfilled += bool(body.get("_backfilled"))
        elif msg.topic == "/agent/EPISODE_END":
            body = msg.json()
            reason = body["reason"]
            outcome = EndReason(reason).name.lower() if reason in (1, 2, 3) else str(reason)
            summary.episodes.append(EpisodeSummary(body["episode"], outcome, body["steps"], body["duration_s"],
                                                   body["episode_return"], bool(body.get("_backfilled"))))
        elif msg.topic == "/agent/HELLO":
            summary.sessions += 1
        elif msg.topic == "/event" and msg.json().get("kind") == "link_lost":
            summary.link_losses += 1
        elif msg.topic == "/link":
            link = msg.json().get("link", {})
            summary.frames_lost = int(link.get("rx_lost", 0))
            summary.rejects = int(link.get("rx_rejects", 0))
    summary.complete = not info.truncated
    summary.episodes.sort(key=lambda e: e.episode)
    summary.successes = sum(e.outcome == "success" for e in summary.episodes)
    summary.samples_missing = sum(b - a for a, b in held.missing())
    summary.duration_s = (last_ns - first_ns) / 1e9 if first_ns is not None and last_ns is not None else 0.0
    for name, key in (("agent_hello", "agent"), ("parameters", "parameters")):
        if info.metadata.get(name):
            setattr(summary, key, info.metadata[name][-1])
    return summary


def format_summary(s: RecordingSummary) -> str:
    agent = s.agent.get("name", "?")
    lines = [
        f"{s.path}{'' if s.complete else '  (truncated: run `dive log recover`)'}",
        f"  agent {agent} id {s.agent.get('node_id', '?')}, {s.sessions} session(s), {s.link_losses} link loss(es), "
        f"{s.duration_s:.1f} s, {s.messages} messages",
        f"  samples {s.samples} ({s.samples_backfilled} backfilled, {s.samples_missing} still missing), "
        f"frames lost {s.frames_lost}, rejects {s.rejects}",
        f"  episodes {len(s.episodes)} ({s.successes} successes)",
    ]
    for e in s.episodes:
        lines.append(f"    {e.episode:5d}  {e.outcome:8s} {e.steps:6d} steps  {e.duration_s:8.1f} s  "
                     f"return {e.episode_return:9.1f}{'  (backfilled)' if e.backfilled else ''}")
    return "\n".join(lines)
