"""Reads an .rrd back with Rerun's own API: rows per entity (static rows left out)."""

from __future__ import annotations

from collections import Counter
from collections.abc import Iterable
from pathlib import Path
from typing import Any

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


def _component_rows(chunks: Iterable[rrc.Chunk], entity: str | None) -> list[dict[str, Any]]:
    rows: list[tuple[bytes, dict[str, Any]]] = []
    for chunk in chunks:
        if entity is not None and chunk.entity_path != entity:
            continue
        batch = chunk.to_record_batch()
        components = [name for name in batch.schema.names if ":" in name]  # "Archetype:field"; not the timelines
        row_ids = batch.column(0).to_pylist()
        for i, row_id in enumerate(row_ids):
            rows.append((row_id, {name: batch.column(name)[i].as_py() for name in components}))
    rows.sort(key=lambda row: row[0])  # row ids grow with logging time
    return [components for _row_id, components in rows]


def latest(path: Path, entity: str) -> dict[str, Any]:
    """The components of the entity's last logged row ({"Points2D:labels": [...], ...}), as Rerun reads them."""
    rows = _component_rows(rrc.RrdReader(path).stream().collect().stream(), entity)
    assert rows, f"{entity} has no rows"
    return rows[-1]


def blueprint_values(path: Path, component: str) -> list[Any]:
    """Every value the recording's blueprints gave `component` ("ScalarAxis:range"), in the order they were sent."""
    reader = rrc.RrdReader(path)
    chunks = [chunk for store in reader.blueprints() for chunk in reader.stream(store=store).collect().stream()]
    return [row[component] for row in _component_rows(chunks, None) if component in row]  # each one a new store


def component_rows(path: Path, entity: str) -> list[dict[str, Any]]:
    """Every logged row of the entity, in logging order ({"Scalars:scalars": [...], ...}), as Rerun reads them."""
    return _component_rows(rrc.RrdReader(path).stream().collect().stream(), entity)
