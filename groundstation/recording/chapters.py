"""The learner's chapters in a recording: a learner restart starts a new generation, and episodes number from 1 again.

A 1.3 agent sends its learner generation in HELLO, HEARTBEAT, EPISODE_START and EPISODE_END (SPEC.md s. 6), so an
episode is keyed by (boot, generation, episode) everywhere. A 1.0-1.2 agent sends none (the field is absent from an
old recording's JSON, or 0 from a 1.2 agent recorded by a 1.3 ground): the restart is then inferred from what the
recording shows, in file order: an accepted CMD_RESET_MODEL, the agent's "learner restarted" / "model reset" TEXT,
or an EPISODE_START whose number does not go up. The inferred chapters are marked so (`Restart.inferred`).

SAMPLEs carry no generation (a backfilled one arrives late): a sample takes the generation of the chapter its index
lies in, each chapter beginning at the first sample index known to be its own (its first EPISODE_START, or the
log_next_sample of the first HEARTBEAT that carried it).
"""

from __future__ import annotations

from bisect import bisect_right
from dataclasses import dataclass
from typing import Any

from groundstation.recording.recorded import json_object
from protocol import AckResult
from protocol import messages as m

HELLO, HEARTBEAT, TEXT, ACK = "/agent/HELLO", "/agent/HEARTBEAT", "/agent/TEXT", "/agent/ACK"
EPISODE_START, EPISODE_END = "/agent/EPISODE_START", "/agent/EPISODE_END"
# What a 1.0-1.2 agent (ours, Python or C) says when its learner restarts; any agent's reset-model ACK counts too.
_RESTART_WORDS = ("learner restarted", "model reset")
_RESET_MODEL_ID = m.ResetModel.DEFINITION.msg_id


@dataclass(frozen=True)
class Restart:
    """A new chapter: where the learner of `boot` started afresh as `generation`."""

    boot: int
    generation: int
    inferred: bool  # the recording carries no generation (a 1.0-1.2 agent): read from its TEXT, ACKs, episodes
    why: str
    after_episode: int  # the last episode number of the chapter before (0: none ran)
    previous: int = 0  # the generation of the chapter before


def wire_generation(body: dict[str, Any]) -> int:
    """The generation a message carries; 0 when it carries none (a 1.0-1.2 agent, or an old recording)."""
    value = body.get("generation", 0)
    return value if isinstance(value, int) and not isinstance(value, bool) and value > 0 else 0


def restart_words(text: str) -> bool:
    """The agent's TEXT says its learner restarted (what ours say; any agent's ACKs and episodes count too)."""
    return any(word in text for word in _RESTART_WORDS)


class Chapters:
    """Follows a recording's messages in file order and says which generation each belongs to."""

    def __init__(self) -> None:
        self.restarts: list[Restart] = []
        self._boot = 0
        self.current = 1
        self.number = 0  # the chapter in file order, 1, 2, ... (a boot's first learner, then each restart)
        self._pending = ""  # why the learner restarted, inferred, before the next episode starts
        self._last_episode = 0
        self._from_wire = False
        self._first_sample: dict[tuple[int, int], int] = {}  # (boot, generation) -> first sample index known

    def follow(self, boot: int, topic: str, body: dict[str, Any]) -> int:
        """The generation of this message (for SAMPLEs: the chapter at the time it arrived, see sample_generation)."""
        if boot != self._boot:  # a reboot: the first learner of a boot is generation 1 (or what the wire says)
            self._boot, self.current, self._pending, self._last_episode = boot, 1, "", 0
            self.number += 1
            self._from_wire = False
        wire = wire_generation(body)
        if topic == TEXT and restart_words(str(body.get("text", ""))):
            self._pending = self._pending or f"the agent said \"{body.get('text')}\""
        elif topic == ACK and body.get("cmd_msg_id") == _RESET_MODEL_ID and body.get("result") == AckResult.ACCEPTED:
            self._pending = self._pending or "CMD_RESET_MODEL was accepted"
        if wire:
            if not self._from_wire:  # the first the boot's frames name: where the recording joined it
                self._from_wire, self.current = True, wire
            elif wire != self.current:
                self._restart(wire, False, self._pending or "the agent's generation went up")
            if topic == EPISODE_START:
                self._note_first(int(body.get("sample", -1)))
                self._last_episode = int(body.get("episode", 0))
            elif topic == HEARTBEAT:
                self._note_first(int(body.get("log_next_sample", -1)))
            return wire
        if self._from_wire or topic != EPISODE_START:
            return self.current
        episode = int(body.get("episode", 0))  # a 1.0-1.2 agent: the restart inferred
        if self._pending or (self._last_episode and episode <= self._last_episode):
            self._restart(self.current + 1, True, self._pending or f"episode {episode} followed "
                          f"episode {self._last_episode}")
        self._last_episode = episode
        self._note_first(int(body.get("sample", -1)))
        return self.current

    def _restart(self, generation: int, inferred: bool, why: str) -> None:
        self.restarts.append(Restart(self._boot, generation, inferred, why, self._last_episode, self.current))
        self.current, self._pending, self._last_episode = generation, "", 0
        self.number += 1

    def _note_first(self, sample: int) -> None:
        key = (self._boot, self.current)
        if sample >= 0 and sample < self._first_sample.get(key, sample + 1):
            self._first_sample[key] = sample

    def sample_generations(self) -> SampleChapters:
        """What sample_generation needs, once the whole recording was followed."""
        return SampleChapters(self._first_sample)


class SampleChapters:
    """Per boot, the sample index each chapter begins at: a sample's generation is the last chapter begun by it."""

    def __init__(self, first_sample: dict[tuple[int, int], int]) -> None:
        self._bounds: dict[int, tuple[list[int], list[int]]] = {}
        for (boot, generation), sample in sorted(first_sample.items(), key=lambda kv: (kv[0][0], kv[1], kv[0][1])):
            starts, generations = self._bounds.setdefault(boot, ([], []))
            starts.append(sample)
            generations.append(generation)

    def generation(self, boot: int, sample: int) -> int:
        starts, generations = self._bounds.get(boot, ([], []))
        i = bisect_right(starts, sample) - 1
        return generations[max(i, 0)] if generations else 1


CHAPTER_TOPICS = (HELLO, TEXT, ACK, EPISODE_START)  # besides EPISODE_END: what says where a chapter begins


def follow_recorded(chapters: Chapters, boot: int, topic: str, data: bytes | str) -> dict[str, Any] | None:
    """A recorded message of CHAPTER_TOPICS or EPISODE_END, followed: its JSON body with `boot` and `generation`
    set, or None when it is not a JSON object (malformed: the caller counts it)."""
    body = json_object(data)
    if body is None:
        return None
    body["generation"] = chapters.follow(boot, topic, body)
    body["boot"] = boot
    return body


@dataclass(frozen=True)
class ChapterSummary:
    """One chapter of `dive log info`: a learner's episodes in one boot, and how the chapter began."""

    boot: int
    generation: int
    episodes: int
    successes: int
    inferred: bool = False
    why: str = ""  # empty for a boot's first learner


def chapter_summaries(restarts: list[Restart], ends: list[tuple[int, int, str]]) -> list[ChapterSummary]:
    """Per (boot, generation): the episodes ended and their successes (`ends`: boot, generation, outcome)."""
    figures: dict[tuple[int, int], list[int]] = {}
    for boot, generation, outcome in ends:
        counts = figures.setdefault((boot, generation), [0, 0])
        counts[0] += 1
        counts[1] += outcome == "success"
    began = {(r.boot, r.generation): r for r in restarts}
    for r in restarts:  # a chapter a restart began, and the one it ended, even without an episode
        figures.setdefault((r.boot, r.generation), [0, 0])
        figures.setdefault((r.boot, r.previous), [0, 0])
    out = []
    for (boot, generation), (episodes, successes) in sorted(figures.items()):
        restart = began.get((boot, generation))
        out.append(ChapterSummary(boot, generation, episodes, successes, bool(restart and restart.inferred),
                                  restart.why if restart else ""))
    return out


def chapter_line(number: int, c: ChapterSummary) -> str:
    """How `dive log info` names a chapter: its number in the recording (what `dive replay --from 2:5` takes)."""
    began = f": the learner restarted ({c.why}" + (", inferred: the recording carries no generation)" if c.inferred
                                                    else ")") if c.why else ""
    return (f"chapter {number} (boot {c.boot}, generation {c.generation}){began}: {c.episodes} episode(s), "
            f"{c.successes} success(es)")
