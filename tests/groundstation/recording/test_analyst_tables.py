"""The Parquet tables answer an analyst's questions with no hand-written join beyond WHERE and GROUP BY (issue 40
item 4): link statistics with RTT and loss, the agent's clock on markers, labelled modes and actions, the target on
every sample, the wire's float32 without noise. A real recorder's file, the real CLI, DuckDB on the export."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from groundstation import open_recording
from groundstation.cli.app import app
from groundstation.recording.recorder import Recorder, RecorderConfig
from groundstation.session.events import EventKind, LinkEvent
from tests.groundstation.synthetic_agent import START_NS, generate, play_session

duckdb = pytest.importorskip("duckdb")

MARKS_S = (30.0, 95.5, 150.0)  # host seconds after the start: markers an operator set while the agent learned


@pytest.fixture(scope="module")
def tables(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    folder = tmp_path_factory.mktemp("analyst")
    recording = folder / "day1" / "run.mcap"  # in a subfolder: the export reads folders recursively
    recording.parent.mkdir()
    recorder = Recorder(RecorderConfig(path=recording))
    recorder.set_parameters({"target_depth_m": 0.5})
    try:
        play_session(generate(duration_s=200.0, seed=3), [recorder])
        for i, t_s in enumerate(MARKS_S):
            text = f"mark {i}"
            recorder.on_event(LinkEvent(EventKind.MARKER, START_NS + int(t_s * 1e9), text, {"text": text}))
    finally:
        recorder.close()
    out = folder / "tables"
    done = CliRunner().invoke(app, ["log", "export", str(folder), "--format", "parquet", "--out", str(out)])
    assert done.exit_code == 0, done.output
    assert f"read 1 .mcap file(s) in {folder} (1 in subfolders)" in done.stderr, done.stderr
    return recording, out


def test_rtt_and_loss_per_minute(tables: tuple[Path, Path]) -> None:
    recording, out = tables
    rows = duckdb.sql(f"SELECT host_time_ns // 60000000000 AS minute, avg(link_rtt_median_ms), "
                      f"max(link_loss_fraction), count(*) FROM '{out}/link/*.parquet' GROUP BY minute "
                      "ORDER BY minute").fetchall()
    link = open_recording(recording).table("/link")  # the same from the recording's own rows
    minutes = link["host_time_ns"] // 60_000_000_000
    expected = [(int(minute), pytest.approx(float(link["link_rtt_median_ms"][minutes == minute].mean())), 0.01,
                 int((minutes == minute).sum())) for minute in np.unique(minutes)]
    assert rows == expected and len(rows) == 4  # 200 s: minutes 0-3


def test_samples_within_2_s_of_each_marker(tables: tuple[Path, Path]) -> None:
    recording, out = tables
    rows = duckdb.sql(f"SELECT m.text, count(*), min(s.mode_name), min(s.target_depth_m) "
                      f"FROM '{out}/marker/*.parquet' m, '{out}/samples/*.parquet' s "
                      "WHERE abs(s.t_us - m.agent_t_us) <= 2000000 GROUP BY m.text ORDER BY m.text").fetchall()
    samples = open_recording(recording).samples()
    expected = [(f"mark {i}", int((np.abs(samples["t_us"] - t_s * 1e6) <= 2e6).sum()), "LEARNING", 0.5)
                for i, t_s in enumerate(MARKS_S)]  # synthetic agent time runs with host time from the start
    assert rows == expected and all(count == 41 for _, count, _, _ in rows)  # 10 Hz: 4 s and both ends


def test_enums_are_labelled_and_float32_is_the_wire_s(tables: tuple[Path, Path]) -> None:
    _, out = tables
    actions = duckdb.sql(f"SELECT DISTINCT action, action_name FROM '{out}/samples/*.parquet' ORDER BY action")
    assert actions.fetchall() == [(0, "decrease_volume"), (1, "increase_volume")]
    [(duration, text)] = duckdb.sql(f"SELECT duration_s, duration_s::VARCHAR FROM '{out}/episodes/*.parquet' "
                                    "WHERE episode = 2").fetchall()
    assert text == "2.6" and duration == pytest.approx(2.6)  # 26 steps; float32 2.6, not 2.5999999046325684


def test_polars_answers_the_same_without_a_join(tables: tuple[Path, Path]) -> None:
    pl = pytest.importorskip("polars")
    _, out = tables
    link = pl.scan_parquet(f"{out}/link/*.parquet")
    per_minute = (link.group_by((pl.col("host_time_ns") // 60_000_000_000).alias("minute"))
                  .agg(pl.col("link_rtt_median_ms").mean(), pl.col("link_loss_fraction").max(), pl.len())
                  .sort("minute").collect())
    duck = duckdb.sql(f"SELECT host_time_ns // 60000000000 AS minute, avg(link_rtt_median_ms), "
                      f"max(link_loss_fraction), count(*) FROM '{out}/link/*.parquet' GROUP BY minute "
                      "ORDER BY minute").fetchall()
    assert [tuple(row) for row in per_minute.iter_rows()] == [pytest.approx(row) for row in duck]
    samples = pl.scan_parquet(f"{out}/samples/*.parquet")
    markers = pl.read_parquet(f"{out}/marker/*.parquet")
    near = {text: samples.filter((pl.col("t_us") - at).abs() <= 2_000_000).select(pl.len()).collect().item()
            for text, at in markers.select("text", "agent_t_us").iter_rows()}
    assert near == {f"mark {i}": 41 for i in range(len(MARKS_S))}
    assert samples.select(pl.col("mode_name").unique()).collect().to_series().to_list() == ["LEARNING"]
