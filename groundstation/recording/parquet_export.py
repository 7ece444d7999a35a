"""`dive log export --format parquet`: a recording as Parquet tables, a folder of recordings as one dataset.

    OUT/samples/NAME.parquet      one row per SAMPLE (each once, by boot then index): every field
    OUT/episodes/NAME.parquet     one row per episode: outcome, first/last sample, steps, return, agent times
    OUT/agent_HEARTBEAT/NAME.parquet, OUT/ground_CMD_START/..., OUT/event/...: every other JSON topic

Every row carries `recording` (NAME), `boot` (1, 2, ... in the recording), `boot_id` (the agent's, hex),
for the agent's messages (samples and episodes included) `generation` (the learner's chapter in its boot: an
episode is keyed by boot, generation and episode), `host_time_ns` and, for the agent's messages, its own clock
`t_us`. Each file's schema metadata holds the session's header (`dive.parameters`, `dive.agent`,
`dive.session`, `dive.environment`, as JSON). One file per
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
from groundstation.recording.environments import environment, tidy_number
from groundstation.recording.safe_files import replaced_atomically
from groundstation.recording.tables import SAMPLE_TOPIC, Recording

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
    tables: dict[str, NDArray[np.void]] = {"samples": recording.samples(), "episodes": recording.episodes()}
    for topic in sorted(recording.topics):
        if topic not in (SAMPLE_TOPIC, "/raw/rx", "/raw/tx") and not topic.startswith("/dump/"):
            rows_of_topic = recording.table(topic)
            if len(rows_of_topic):
                tables[table_name(topic)] = rows_of_topic
    if not len(tables["samples"]) and not len(tables["episodes"]):
        raise RecordingError(f"{name} holds no samples or episodes to export")
    written: dict[str, int] = {}
    for table, rows in tables.items():
        columns: dict[str, Any] = {"recording": pa.array([name] * len(rows), pa.string())}
        boots = rows["boot"] if "boot" in (rows.dtype.names or ()) else np.zeros(len(rows), dtype=np.int64)
        columns["boot"] = pa.array(boots.astype(np.int64))
        columns["boot_id"] = pa.array([boot_ids.get(int(b)) for b in boots], pa.string())
        if "generation" in (rows.dtype.names or ()):
            columns["generation"] = _column(pa, rows["generation"])
        for field in rows.dtype.names or ():
            if field in _LEFT_OUT or field in ("boot", "generation"):
                continue
            columns[field] = _column(pa, rows[field])
        arrow = pa.table(columns).replace_schema_metadata(metadata)
        target = out_dir / table / f"{name}.parquet"
        target.parent.mkdir(parents=True, exist_ok=True)
        with replaced_atomically(target) as temporary:
            pq.write_table(arrow, temporary)
        written[table] = len(rows)
    return written


def _column(pa: Any, values: NDArray[Any]) -> Any:
    """A typed Arrow column: integers int64, numbers float64, flags bool, text string (JSON's types, widened)."""
    kind = values.dtype.kind
    if kind in "iu":
        return pa.array(values.astype(np.int64))
    if kind == "f":
        return pa.array(values.astype(np.float64))
    if kind == "b":
        return pa.array(values.astype(bool))
    return pa.array([None if v is None else str(v) for v in values.tolist()], pa.string())
