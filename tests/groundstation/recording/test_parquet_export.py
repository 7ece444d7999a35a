"""`dive log export --format parquet` (issue 28 item 3): a folder of recordings as Parquet tables that DuckDB,
pandas-free, queries as one dataset; typed columns, the session's header as metadata. Real recordings by the
real recorder, the real CLI, the files read back by pyarrow and DuckDB."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from groundstation import open_recording
from groundstation.cli.app import app
from groundstation.recording.recorder import Recorder, RecorderConfig
from groundstation.session.events import Received
from protocol import Frame, Mode
from protocol import messages as m
from protocol.frame import build_inner
from tests.groundstation.synthetic_agent import generate, play_session

duckdb = pytest.importorskip("duckdb")


def _rebooted(received: Received, boot_id: int) -> Received:
    frame = received.frame
    if not isinstance(frame.message, m.Hello):
        return received
    hello = m.Hello(**{**frame.message.to_dict(), "boot_id": boot_id})
    inner = build_inner(frame.flags, frame.seq, frame.msg_id, hello.pack())
    return received._replace(frame=Frame(frame.flags, frame.seq, frame.msg_id, hello, inner))


@pytest.fixture(scope="module")
def folder(tmp_path_factory: pytest.TempPathFactory) -> Path:
    folder = tmp_path_factory.mktemp("runs")
    for seed, boot_id in ((1, 0xB1), (2, 0xB2)):
        traffic = generate(duration_s=1700.0, seed=seed)  # episodes grow to the 3000-step success at the end
        traffic.frames[:] = [_rebooted(r, boot_id) for r in traffic.frames]
        recorder = Recorder(RecorderConfig(path=folder / f"run{seed}.mcap"))
        recorder.set_parameters({"target_depth_m": 0.5, "gravity_mps2": 9.800000190734863})
        try:
            play_session(traffic, [recorder])
        finally:
            recorder.close()
    return folder


def test_duckdb_queries_a_folder_of_recordings_as_one_dataset(folder: Path, tmp_path: Path) -> None:
    out = tmp_path / "tables"
    done = CliRunner().invoke(app, ["log", "export", str(folder), "--format", "parquet", "--out", str(out)])
    assert done.exit_code == 0, done.output
    episodes, samples = f"'{out}/episodes/*.parquet'", f"'{out}/samples/*.parquet'"
    per_boot = duckdb.sql(f"SELECT boot_id, count(*) FILTER (WHERE outcome = 'success') FROM {episodes} "
                          "GROUP BY boot_id ORDER BY boot_id").fetchall()
    error = duckdb.sql(f"SELECT avg(abs(s.depth_m - 0.5)) FROM {samples} s JOIN {episodes} e "
                       "USING (recording, boot, episode) WHERE e.outcome = 'success' AND s.mode = 1").fetchall()
    # The same figures from the recordings themselves (open_recording, numpy)
    expected_boots, depth_errors = [], []
    for seed, boot_id in ((1, "000000b1"), (2, "000000b2")):
        rec = open_recording(folder / f"run{seed}.mcap")
        ends = rec.episodes()
        won = ends[ends["outcome"] == "success"]
        expected_boots.append((boot_id, len(won)))
        rows = rec.samples()
        held = np.isin(rows["episode"], won["episode"]) & (rows["mode"] == int(Mode.LEARNING))
        depth_errors.append(np.abs(rows["depth_m"][held] - 0.5))
    assert per_boot == expected_boots and all(n >= 1 for _, n in per_boot)
    # depth_m is the wire's float32 (issue 40): DuckDB subtracts in float32, numpy here in float64
    assert error[0][0] == pytest.approx(float(np.concatenate(depth_errors).mean()), rel=1e-6)


def test_columns_are_typed_and_the_header_is_metadata(folder: Path, tmp_path: Path) -> None:
    import pyarrow.parquet as pq

    out = tmp_path / "tables"
    assert CliRunner().invoke(app, ["log", "export", str(folder / "run1.mcap"), "--format", "parquet", "--out",
                                    str(out)]).exit_code == 0
    table = pq.read_table(out / "samples" / "run1.parquet")
    types = {field.name: str(field.type) for field in table.schema}
    assert {"recording": "string", "boot": "int64", "boot_id": "string", "t_us": "int64", "host_time_ns": "int64",
            "sample": "int64", "depth_m": "float", "_backfilled": "bool"}.items() <= types.items()
    meta = table.schema.metadata
    assert json.loads(meta[b"dive.parameters"])["gravity_mps2"] == "9.8"
    assert json.loads(meta[b"dive.agent"])["name"] == "synthetic"
    assert (out / "agent_HEARTBEAT" / "run1.parquet").is_file() and (out / "episodes" / "run1.parquet").is_file()
