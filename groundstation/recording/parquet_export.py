"""`dive log export --format parquet`: a recording as Parquet tables, a folder of recordings as one dataset.

    OUT/samples/NAME.parquet      one row per SAMPLE (each once, by boot then index): every field
    OUT/episodes/NAME.parquet     one row per episode: outcome, first/last sample, steps, return, agent times
    OUT/agent_HEARTBEAT/NAME.parquet, OUT/ground_CMD_START/..., OUT/event/...: every other JSON topic

Every row carries `recording` (NAME), `boot` (1, 2, ... in the recording), `boot_id` (the agent's, hex),
`generation` for the agent's messages (samples and episodes included: the learner's chapter in its boot, an
episode is keyed by boot, generation and episode), `host_time_ns` and, for the agent's messages, its own clock
`t_us`; the ground's rows (markers, events, link statistics with RTT, loss and backfill) carry the agent's clock
as `agent_t_us`, modes and actions their names, samples their episode's target (recording/analyst_columns.py).
Each file's schema metadata holds the session's header (`dive.parameters`, `dive.agent`, `dive.session`,
`dive.environment`, as JSON). One file per
recording in one folder per table, with the same columns and types, is what pandas (`read_parquet(OUT/"samples")`),
polars (`scan_parquet("OUT/samples/*.parquet")`) and DuckDB (`FROM 'OUT/samples/*.parquet'`) read as one table.
"""

from __future__ import annotations

import json
import re
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from groundstation.errors import RecordingError
from groundstation.recording.analyst_columns import LABELLED, AgentClock, float32_fields, label, sample_targets
from groundstation.recording.environments import environment, tidy_number
from groundstation.recording.safe_files import replaced_atomically
from groundstation.recording.tables import EPISODE_START_TOPIC, SAMPLE_TOPIC, Recording

_LEFT_OUT = {"_seq", "_flags"}  # the link's bookkeeping, not data


def table_name(topic: str) -> str:
    """/agent/HEARTBEAT -> agent_HEARTBEAT (a folder name every tool and shell takes)."""
    return re.sub(r"[^A-Za-z0-9_]+", "_", topic).strip("_") or "topic"


def export_parquet(recording: Recording, name: str, out_dir: Path) -> dict[str, int]:
    """Write the recording's tables under out_dir (one folder per table); rows written per table."""
    try:
        import pyarrow as pa
        import pyarrow.parquet as pq
    except ImportError as e:  # a dependency (rerun-sdk needs it too): only a broken install lacks it
        raise RecordingError("--format parquet needs pyarrow: pip install pyarrow") from e
    metadata = {
        b"dive.parameters": json.dumps({k: tidy_number(v) for k, v in recording.parameters.items()}).encode(),
        b"dive.agent": json.dumps(recording.agent).encode(),
        b"dive.session": json.dumps((recording.metadata.get("session") or [{}])[0]).encode(),
        b"dive.environment": json.dumps(environment(recording.metadata)).encode(),
    }
    boot_ids = {boot: f"{boot_id:08x}" for boot, boot_id in recording.boot_ids.items()}
    samples = recording.samples()
    tables: dict[str, NDArray[np.void]] = {"samples": samples, "episodes": recording.episodes()}
    topics = {"samples": SAMPLE_TOPIC, "episodes": "/agent/EPISODE_END"}
    for topic in sorted(recording.topics):
        if topic not in (SAMPLE_TOPIC, "/raw/rx", "/raw/tx") and not topic.startswith("/dump/"):
            rows_of_topic = recording.table(topic)
            if len(rows_of_topic):
                tables[table_name(topic)] = rows_of_topic
                topics[table_name(topic)] = topic
    if not len(tables["samples"]) and not len(tables["episodes"]):
        raise RecordingError(f"{name} holds no samples or episodes to export")
    clock = AgentClock(samples)
    starts = recording.table(EPISODE_START_TOPIC) if EPISODE_START_TOPIC in recording.topics else samples[:0]
    target_m = _number(recording.parameters.get("target_depth_m"))  # the samples' before the first episode
    written: dict[str, int] = {}
    for table, rows in tables.items():
        columns: dict[str, Any] = {"recording": pa.array([name] * len(rows), pa.string())}
        fields = rows.dtype.names or ()
        boots = rows["boot"] if "boot" in fields else np.zeros(len(rows), dtype=np.int64)
        columns["boot"] = pa.array(boots.astype(np.int64))
        columns["boot_id"] = pa.array([boot_ids.get(int(b)) for b in boots], pa.string())
        single = float32_fields(topics.get(table, ""))  # the episodes' duration and return: EPISODE_END's
        if "generation" in fields:
            columns["generation"] = _column(pa, rows["generation"])
        for field in fields:
            if field in _LEFT_OUT or field in ("boot", "generation"):
                continue
            columns[field] = _column(pa, rows[field], field in single)
            if field in LABELLED and rows.dtype[field].kind in "iu":
                labelled, names = LABELLED[field]
                columns[labelled] = pa.array(label(rows[field], names), pa.string()).dictionary_encode()
        if "t_us" not in fields and "host_time_ns" in fields:  # the ground's rows: the agent's clock beside
            columns["agent_t_us"] = pa.array(clock.agent_us(boots, rows["host_time_ns"]), pa.int64())
        if table == "samples":
            columns["target_depth_m"] = pa.array(sample_targets(rows, starts, target_m), pa.float32())
        arrow = pa.table(columns).replace_schema_metadata(metadata)
        target = out_dir / table / f"{name}.parquet"
        target.parent.mkdir(parents=True, exist_ok=True)
        with replaced_atomically(target) as temporary:
            pq.write_table(arrow, temporary)
        written[table] = len(rows)
    return written


def _number(text: str | None) -> float | None:
    try:
        return float(text) if text is not None else None
    except ValueError:
        return None


def _column(pa: Any, values: NDArray[Any], single: bool = False) -> Any:
    """A typed Arrow column: integers int64, numbers float64 (float32 for the wire's F32: `single`), flags bool, text
    string (JSON's types, widened)."""
    kind = values.dtype.kind
    if kind in "iu":
        return pa.array(values.astype(np.int64))
    if kind == "f":
        return pa.array(values.astype(np.float32 if single else np.float64))
    if kind == "b":
        return pa.array(values.astype(bool))
    return pa.array([None if v is None else str(v) for v in values.tolist()], pa.string())
