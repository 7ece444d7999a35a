"""Summaries of many recordings: file by file (in worker processes where it pays), combined per split recording
and per agent boot that spans several files."""

from __future__ import annotations

import os
from collections.abc import Callable
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass
from pathlib import Path

from groundstation.recording.info import BootSummary, RecordingSummary, summarize

# Below this much data a second process costs more than it saves (its start and imports take ~0.3 s).
PARALLEL_FROM_BYTES = 32 * 1024 * 1024


def workers() -> int:
    """The cores this process may use."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not Linux
        return os.cpu_count() or 1


def summarize_files(files: list[Path], progress: Callable[[int, int], None] | None = None
                    ) -> list[RecordingSummary]:
    """summarize() of each file, in the order given; progress(bytes done, bytes in all) as files finish.

    Several files holding enough data are summarised by a pool of processes, one per core: each file's read
    is one core's work (decompression and numpy), so a folder goes as fast as the cores allow.
    """
    sizes = [_size(f) for f in files]
    total = sum(sizes)
    done = 0
    cores = min(workers(), len(files))
    if cores < 2 or total < PARALLEL_FROM_BYTES:
        summaries = []
        for f, size in zip(files, sizes, strict=True):
            summaries.append(summarize(f, _offset(progress, done, total)))
            done += size
            if progress is not None:
                progress(done, total)
        return summaries
    with ProcessPoolExecutor(cores) as pool:
        futures = [pool.submit(summarize, f) for f in files]
        results: list[RecordingSummary] = []
        for future, size in zip(futures, sizes, strict=True):
            results.append(future.result())  # in order: a slow first file holds the bar, not the result
            done += size
            if progress is not None:
                progress(done, total)
    return results


def _offset(progress: Callable[[int, int], None] | None, base: int, total: int
            ) -> Callable[[int, int], None] | None:
    """One file's progress as part of all the files' bytes."""
    if progress is None:
        return None
    report = progress
    return lambda done, _of: report(base + done, total)


def _size(path: Path) -> int:
    try:
        return path.stat().st_size
    except OSError:
        return 0


@dataclass(frozen=True, slots=True)
class Combined:
    """Totals over several files: the parts of a split recording, or every file holding one boot of the agent."""

    what: str
    files: int
    duration_s: float
    agent_duration_s: float
    samples: int
    samples_backfilled: int
    samples_missing: int
    episodes: int
    successes: int


def combine(summaries: list[RecordingSummary], recordings: list[list[str]]) -> list[Combined]:
    """One line per recording of several files (`recordings`: each recording's file paths, as group_recordings
    found them) and one per agent boot whose samples lie in several files.

    A boot's samples missing across files: its index span less the samples held, so a hole at a part boundary
    counts (samples are held once in all: a backfilled one lands in the part that was open when it came).
    """
    by_path = {s.path: s for s in summaries}
    lines: list[Combined] = []
    for paths in recordings:
        parts = [by_path[p] for p in paths if p in by_path]
        if len(parts) > 1:
            lines.append(_combined(f"recording {Path(paths[0]).name} and {len(parts) - 1} more part(s)", parts))
    boots: dict[tuple[str, int], list[RecordingSummary]] = {}
    for s in summaries:
        for b in s.boots:
            if b.boot_id is not None and b.samples:
                boots.setdefault((str(s.agent.get("node_id", "?")), b.boot_id), []).append(s)
    for (node_id, boot_id), holders in boots.items():
        if len(holders) > 1:
            lines.append(_boot_line(node_id, boot_id, holders))
    return lines


def _combined(what: str, parts: list[RecordingSummary]) -> Combined:
    boots = [b for s in parts for b in s.boots]
    held, missing = _union(boots)
    return Combined(what, len(parts), sum(s.duration_s for s in parts), sum(s.agent_duration_s for s in parts),
                    held, sum(s.samples_backfilled for s in parts), missing,
                    sum(len(s.episodes) for s in parts), sum(s.successes for s in parts))


def _boot_line(node_id: str, boot_id: int, holders: list[RecordingSummary]) -> Combined:
    mine = [b for s in holders for b in s.boots if b.boot_id == boot_id]
    held, missing = _union(mine)
    node = f"{int(node_id):08x}" if node_id.isdigit() else node_id
    return Combined(f"agent {node} boot {boot_id:08x}", len(holders), sum(s.duration_s for s in holders),
                    sum(s.agent_duration_s for s in holders), held, sum(b.samples_backfilled for b in mine),
                    missing, sum(len(s.episodes) for s in holders), sum(s.successes for s in holders))


def _union(boots: list[BootSummary]) -> tuple[int, int]:
    """(samples held, samples missing) of boots' held ranges together, per agent boot: a sample two files hold
    (a second recorder's copy) counts once, a hole at a part boundary counts as missing."""
    by_boot: dict[int | None, list[tuple[int, int]]] = {}
    for boot in boots:
        by_boot.setdefault(boot.boot_id, []).extend(boot.held)
    held = missing = 0
    for ranges in by_boot.values():
        merged: list[list[int]] = []
        for start, end in sorted(ranges):
            if merged and start <= merged[-1][1]:
                merged[-1][1] = max(merged[-1][1], end)
            else:
                merged.append([start, end])
        held += sum(end - start for start, end in merged)
        missing += sum(b[0] - a[1] for a, b in zip(merged, merged[1:], strict=False))
    return held, missing


def format_combined(c: Combined) -> str:
    return (f"{c.what}: {c.files} files, {c.duration_s:.1f} s host time ({c.agent_duration_s:.1f} s agent time), "
            f"samples {c.samples} ({c.samples_backfilled} backfilled, {c.samples_missing} still missing), "
            f"episodes {c.episodes} ({c.successes} successes)")
