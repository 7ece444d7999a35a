"""A replay's window: `--from` and `--to` parsed, checked, and applied to a recording's items in file order."""

from __future__ import annotations

import re
from collections.abc import Iterator
from dataclasses import dataclass

from groundstation.recording.chapters import Chapters
from groundstation.recording.recorded import Boots
from groundstation.view.errors import ReplayError
from groundstation.view.replay_items import Item
from protocol import NodeKind
from protocol import messages as m

_TIME = re.compile(r"^(\d+(?:\.\d*)?)(s|m|h|min)$")
_UNIT_S = {"s": 1.0, "m": 60.0, "min": 60.0, "h": 3600.0}


@dataclass(frozen=True, slots=True)
class Bound:
    """One end of a replay range: an episode number of a chapter, or a time since the recording's start.

    A learner restart (SPEC 1.3 s. 6) or a reboot numbers the episodes from 1 again: the chapter (1, 2, ... in the
    recording, as `dive log info` numbers them) tells the two learners' episode 5 apart.
    """

    episode: int | None = None
    offset_s: float | None = None
    chapter: int = 1


def parse_bound(text: str) -> Bound:
    """`12` or `e12` is episode 12 (of the first chapter); `2:5` is chapter 2's episode 5; `90s`, `5m`, `1.5h` is a
    time since the start of the recording."""
    text = text.strip().lower()
    chapter, _, episode = text.rpartition(":")
    if episode.removeprefix("e").isdigit() and (not chapter or chapter.isdigit() and int(chapter) >= 1):
        return Bound(episode=int(episode.removeprefix("e")), chapter=int(chapter) if chapter else 1)
    match = _TIME.match(text)
    if match is None:
        raise ReplayError(f"bad range bound {text!r}: give an episode (12, or 2:5 for chapter 2's episode 5) or a "
                          "time (90s, 5m, 1h)")
    return Bound(offset_s=float(match.group(1)) * _UNIT_S[match.group(2)])


def check_order(start: Bound | None, end: Bound | None) -> None:
    """A reversed window is one clear line before anything is read or written."""
    if start is None or end is None:
        return
    if start.episode is not None and end.episode is not None and \
            (start.chapter, start.episode) > (end.chapter, end.episode):
        raise ReplayError(f"--from {_named(start)} is after --to {_named(end)}")
    if start.offset_s is not None and end.offset_s is not None and start.offset_s > end.offset_s:
        raise ReplayError(f"--from {start.offset_s:g} s is after --to {end.offset_s:g} s (agent time)")


def _named(bound: Bound) -> str:
    return f"episode {bound.episode}" + (f" of chapter {bound.chapter}" if bound.chapter > 1 else "")


@dataclass
class Tally:
    """What select() passed over: items shown (setup left out), and how far the recording reached."""

    shown: int = 0
    span_s: float = 0.0  # agent time from the first frame to the last read
    last_episode: int = 0

    def check_window(self, start: str | None, end: str | None) -> None:
        """A window that holds nothing is an error (a past-the-end --from wrote an almost empty .rrd)."""
        if self.shown == 0 and (start is not None or end is not None):
            window = " ".join(part for part in (f"--from {start}" if start else "", f"--to {end}" if end else "")
                              if part)
            raise ReplayError(f"the window {window} holds no agent frames: the recording spans {self.span_s:.0f} s "
                              f"of agent time and episodes up to {self.last_episode}")


# The frames that say where a chapter begins (recording/chapters.py follows the same in `dive log info`)
_CHAPTER_MESSAGES = (m.Hello, m.Text, m.Ack, m.EpisodeStart, m.EpisodeEnd)


class _ItemChapters:
    """The chapter of each item in file order, as `dive log info` numbers them (recording/chapters.py)."""

    def __init__(self) -> None:
        self._chapters = Chapters()
        self._boots = Boots()

    def follow(self, item: Item) -> int:
        message = item.message
        if isinstance(message, _CHAPTER_MESSAGES):
            if isinstance(message, m.Hello):
                if message.node_kind != NodeKind.AGENT:
                    return max(self._chapters.number, 1)
                self._boots.boot(message.boot_id)
            self._chapters.follow(self._boots.current, f"/agent/{message.DEFINITION.name}", message.to_dict())
        return max(self._chapters.number, 1)


def select(items: Iterator[Item], start: Bound | None, end: Bound | None,
           tally: Tally | None = None) -> Iterator[Item]:
    """Only the items inside [start, end]: episodes by the agent's episode number, times in agent time.

    Agent time (the messages' own clock) is the timeline the viewer shows and --speed plays: at --speed max a
    minute of host time holds hours of agent time. A record without a clock of its own (an event, a marker)
    takes the agent time of the frame before it. Backfilled frames come later in the file than their time:
    past a time bound the rest of the file is still read for them.
    """
    first_s: float | None = None
    latest_s = 0.0
    episode = 0
    chapters = _ItemChapters()
    for item in items:
        if item.setup:
            yield item
            continue
        chapter = chapters.follow(item)
        if item.agent_time_s is not None:
            first_s = item.agent_time_s if first_s is None else first_s
            latest_s = item.agent_time_s
        episode = item.episode if item.episode is not None else episode
        offset_s = latest_s - first_s if first_s is not None else 0.0
        if tally is not None:
            tally.span_s, tally.last_episode = max(tally.span_s, offset_s), max(tally.last_episode, episode)
        if start is not None and (
            (start.episode is not None and (chapter, episode) < (start.chapter, start.episode))
            or (start.offset_s is not None and offset_s < start.offset_s)
        ):
            item.before = True  # fed for the heatmaps and curve the window opens on, not shown
            yield item
            continue
        if end is not None and end.episode is not None and (chapter, episode) > (end.chapter, end.episode):
            break
        if end is not None and end.offset_s is not None and offset_s > end.offset_s:
            continue
        if tally is not None:
            tally.shown += 1
        yield item
