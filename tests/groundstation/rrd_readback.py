"""Reads an .rrd back with Rerun's own API: rows per entity (static rows left out)."""

from __future__ import annotations

from collections import Counter
from pathlib import Path

import rerun.chunk as rrc


def rows_per_entity(path: Path) -> Counter[str]:
    store = rrc.RrdReader(path).stream().collect()
    rows: Counter[str] = Counter()
    for chunk in store.stream():
        if not chunk.is_static:
            rows[chunk.entity_path] += chunk.num_rows
    return rows


def timelines(path: Path, entity: str) -> set[str]:
    store = rrc.RrdReader(path).stream().collect()
    return {name for chunk in store.stream() if chunk.entity_path == entity for name in chunk.timeline_names}
