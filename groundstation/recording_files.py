"""Recordings as people point at them: several files or a folder, a file still being recorded, JSON for machines."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

from groundstation.errors import GroundStationError

_HEX_IDS = ("node_id", "boot_id")  # shown in hex everywhere else (dive status, file names)


def expand(paths: list[Path]) -> list[Path]:
    """Each file as given, each folder as its .mcap files in name order (split parts sort: part002 < part010)."""
    found: list[Path] = []
    for path in paths:
        if path.is_dir():
            inside = sorted(path.glob("*.mcap"))
            if not inside:
                raise GroundStationError(f"no .mcap recordings in {path}")
            found.extend(inside)
        elif path.is_file():
            found.append(path)
        else:
            raise GroundStationError(f"no such recording: {path}")
    return found


def being_recorded(path: Path) -> str | None:
    """`dive run N` when a run on this machine is writing `path` now (so a missing footer is not damage)."""
    from groundstation.runs import running

    try:
        target = path.resolve()
    except OSError:
        return None
    for run in running():
        if run.recording and Path(run.recording).resolve() == target:
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
        return value_f if math.isfinite(value_f) else text
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
    return out
