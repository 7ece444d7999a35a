"""Recordings as people point at them: several files or a folder, a file still being recorded, JSON for machines."""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from groundstation.errors import GroundStationError
from groundstation.recording.environments import tidy_value

_HEX_IDS = ("node_id", "boot_id")  # shown in hex everywhere else (dive status, file names)


def _empty(path: Path) -> bool:
    try:
        return path.stat().st_size == 0
    except OSError:
        return False  # read (and reported) as it is


def expand(paths: list[Path]) -> list[Path]:
    """Each file as given, each folder as the .mcap files in it and its subfolders (a tank day's recordings sorted
    into a folder per day) in path order (split parts sort: part002 < part010).

    An empty file in a folder is passed over: it holds nothing, and kill -9 as a split part was created leaves one
    (issue 25 M2); refusing the folder for it would refuse every part that holds the recording."""
    found: list[Path] = []
    for path in paths:
        if path.is_dir():
            inside = [f for f in sorted(path.rglob("*.mcap"), key=lambda f: f.parts) if not _empty(f)]
            if not inside:
                raise GroundStationError(f"no .mcap recordings in {path}")
            found.extend(inside)
        elif path.is_file():
            found.append(path)
        else:
            raise GroundStationError(f"no such recording: {path}")
    return found


def read_line(paths: list[Path], found: list[Path]) -> str | None:
    """The line naming what folders given were read as ("read 14 .mcap files in recordings/ (3 in subfolders)"),
    None when only files were given: a subfolder read, or one passed over, is never silent."""
    folders = [p for p in paths if p.is_dir()]
    if not folders:
        return None
    parts = []
    for folder in folders:
        inside = [f for f in found if f.is_relative_to(folder)]
        deeper = sum(f.parent != folder for f in inside)
        parts.append(f"{len(inside)} .mcap file(s) in {folder}" + (f" ({deeper} in subfolders)" if deeper else ""))
    return "read " + "; ".join(parts)


_PART = re.compile(r"-part\d+$")

Header = dict[str, list[dict[str, str]]]  # a file's metadata records by name (mcap_io.read_header)


@dataclass(frozen=True, slots=True)
class RecordingParts:
    """The files of one recording in part order (a split recording's parts by part number) and the first's header."""

    files: list[Path]
    header: Header
    name: str  # the first file's name without its part number: the recording's name
    missing: list[int]  # part numbers between the first and the last given that were not given


def _session(header: Header) -> dict[str, str]:
    return (header.get("session") or [{}])[0]


def group_recordings(files: list[Path]) -> list[RecordingParts]:
    """The files as recordings, in the order first given: each file's header read (a missing or non-MCAP file is
    a RecordingError here, before anything is written), the parts of a split recording together in part order.
    The same file given twice (by name and through its folder) counts once."""
    from groundstation.mcap_io import read_header

    first_given: dict[Path, Path] = {}
    for f in files:
        first_given.setdefault(f.resolve(), f)  # as the user named it, for the messages and outputs
    unique = list(first_given.values())
    headers = {f: read_header(f) for f in unique}
    grouped: dict[str, list[Path]] = {}
    for f in unique:
        session = _session(headers[f])
        # recording_id since split parts carry it; before that the parts shared the session's URL and start
        key = session.get("recording_id") or (f"{session['url']}|{session['started']}" if "started" in session
                                              and "url" in session else str(f))
        grouped.setdefault(key, []).append(f)

    def part(f: Path) -> int:
        number = _session(headers[f]).get("part", "")
        return int(number) if number.isdigit() else 0

    recordings = []
    for members in grouped.values():
        ordered = sorted(members, key=part)
        numbers = [part(f) for f in ordered]
        for a, b in zip(ordered, ordered[1:], strict=False):
            if part(a) and part(a) == part(b):
                raise GroundStationError(f"{a} and {b} are both part {part(a)} of one recording: give one of them")
        missing = sorted(set(range(numbers[0], numbers[-1] + 1)) - set(numbers)) if numbers[0] else []
        recordings.append(RecordingParts(ordered, headers[ordered[0]], _PART.sub("", ordered[0].stem), missing))
    return recordings


def being_recorded(path: Path) -> str | None:
    """`dive run N` when a run on this machine is writing `path` now (so a missing footer is not damage)."""
    from groundstation.links.runs import running

    try:
        target = path.resolve()
    except OSError:
        return None
    for run in running():
        if run.state != "finished" and run.recording and Path(run.recording).resolve() == target:
            return f"dive run {run.run}"
    return None


def _number(text: Any) -> Any:
    """A metadata string that holds a number (or true/false) as that number; anything else unchanged."""
    if not isinstance(text, str):
        return text
    if text in ("true", "false"):
        return text == "true"
    try:
        value = int(text)
    except ValueError:
        try:
            value_f = float(text)
        except ValueError:
            return text
        return tidy_value(value_f) if math.isfinite(value_f) else text  # float32 parameters without their noise
    return value


def json_summary(summary: dict[str, Any]) -> dict[str, Any]:
    """`dive log info --json`: numbers as numbers, node and boot ids in hex as `dive status` shows them."""
    out = dict(summary)
    agent = {k: _number(v) for k, v in dict(summary.get("agent", {})).items()}
    for key in _HEX_IDS:
        if isinstance(agent.get(key), int):
            agent[key] = f"{agent[key]:08x}"
    out["agent"] = agent
    out["parameters"] = {k: _number(v) for k, v in dict(summary.get("parameters", {})).items()}
    out["boots"] = [{**boot, "boot_id": f"{boot['boot_id']:08x}" if isinstance(boot.get("boot_id"), int) else None}
                    for boot in summary.get("boots", [])]
    return out
