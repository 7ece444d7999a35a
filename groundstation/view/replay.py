"""A replay played in agent time, and the files given to it checked as the parts of one recording.

Its other parts: replay_items.py (a recording read as items), replay_window.py (--from/--to), replay_convert.py
(everything at once, for an .rrd or a viewer that takes columns).
"""

from __future__ import annotations

import time
from collections.abc import Callable, Iterator
from pathlib import Path

from groundstation.mcap_io import RecordingContents
from groundstation.recording.files import RecordingParts as Parts
from groundstation.recording.files import group_recordings
from groundstation.view.errors import ReplayError
from groundstation.view.model import ViewModel
from groundstation.view.replay_items import Item


def play(items: Iterator[Item], sink: Callable[[Callable[[ViewModel], None]], None], speed: float,
         sleep: Callable[[float], None] = time.sleep) -> int:
    """Hand each item to `sink` at its agent time divided by `speed` (backfilled frames: no waiting)."""
    origin_agent_s: float | None = None
    origin_wall = time.monotonic()
    count = 0
    for item in items:
        if item.before:
            continue  # played in time from the window's start (its state would be sent unpaced: not here)
        count += 1
        if item.agent_time_s is not None:
            if origin_agent_s is None:
                origin_agent_s, origin_wall = item.agent_time_s, time.monotonic()
            delay = (item.agent_time_s - origin_agent_s) / speed - (time.monotonic() - origin_wall)
            if delay > 0:
                sleep(delay)
        sink(item.feed)
    return count


def check_nonempty(count: int, path: Path | str, info: RecordingContents) -> None:
    if count == 0:
        cut = " (cut short before its first complete chunk)" if info.truncated else ""
        raise ReplayError(f"{path} holds no agent frames to show{cut}")


class MixedRecordingsError(ReplayError):
    """Files of different recordings given to one replay (bad usage: their agent times overlap)."""


def plan(files: list[Path]) -> Parts:
    """The files given as the parts of one recording, in part order, each one's header read first (so a missing
    or non-MCAP file is one line before anything is shown or written).

    Parts of one split recording play as one timeline: the agent's clock runs on across them. Files of different
    recordings are refused: their agent times overlap (each starts near the agent's boot), one timeline cannot
    hold them, and a user replays one session at a time.
    """
    recordings = group_recordings(files)
    if not recordings:
        raise ReplayError("no recording given")
    if len(recordings) > 1:
        names = ", ".join(r.files[0].name for r in recordings[:3]) + (", ..." if len(recordings) > 3 else "")
        raise MixedRecordingsError(
            f"the files hold {len(recordings)} recordings ({names}): dive replay shows one at a time "
            "(a file, or the parts of a split one)")
    return recordings[0]
