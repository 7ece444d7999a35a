"""The recorded JSON carries the wire's float32 fields at their own precision (issue 40): 8.6, not the widened
8.600000381469727, each the shortest text that is the same float32 the agent sent; and every reader gives the same
figures from a recording written before (its JSON widened) as from one written now.

A real recording: the virtual agent's program stepped into the real recorder; read back with the mcap library.
The "old" file is that recording rewritten by the mcap library with every F32 field widened, as the recorder wrote
them before."""

from __future__ import annotations

import json
import math
import re
from pathlib import Path

import numpy as np
import pyarrow.parquet as pq
from mcap.reader import make_reader
from mcap.writer import Writer
from typer.testing import CliRunner

from groundstation.cli.app import app
from groundstation.mcap_io import iter_messages
from groundstation.recording.analyst_columns import float32_fields
from groundstation.recording.info import summarize, summarize_stream
from groundstation.recording.parquet_export import export_parquet
from groundstation.recording.tables import open_recording
from protocol import message_class
from protocol import messages as m
from protocol.frame import parse_inner
from tests.groundstation.recording.onboard_recording import record_onboard


def _widened(path: Path, old: Path) -> int:
    """`path` rewritten into `old` with every F32 field of its JSON bodies widened to float64's text; how many."""
    changed = 0
    with path.open("rb") as f, old.open("wb") as out:
        reader = make_reader(f)
        writer = Writer(out)
        writer.start(profile=reader.get_header().profile, library="test: the recorder before issue 40")
        for record in reader.iter_metadata():
            writer.add_metadata(record.name, record.metadata)
        schemas: dict[int, int] = {}
        channels: dict[int, int] = {}
        for schema, channel, message in reader.iter_messages(log_time_order=False):
            if channel.id not in channels:
                if schema is not None and schema.id not in schemas:
                    schemas[schema.id] = writer.register_schema(schema.name, schema.encoding, schema.data)
                channels[channel.id] = writer.register_channel(
                    channel.topic, channel.message_encoding, schemas[schema.id] if schema is not None else 0,
                    channel.metadata)
            data = message.data
            single = float32_fields(channel.topic)
            if single:
                body = json.loads(data)
                for name in single:
                    if isinstance(body.get(name), float):
                        body[name] = float(np.float32(body[name]))  # 8.6 -> 8.600000381469727
                        changed += 1
                data = json.dumps(body, separators=(",", ":")).encode()
            writer.add_message(channels[channel.id], message.log_time, data, message.publish_time, message.sequence)
        writer.finish()
    return changed


def test_recorded_float32_fields_are_the_shortest_text_of_the_agents_float32(tmp_path: Path) -> None:
    (path,) = record_onboard(tmp_path / "new.mcap", "paper", "python", seed=2, episodes=3)
    raw = {}
    for msg in iter_messages(path, {"/raw/rx"}):
        frame = parse_inner(msg.data)
        if frame.msg_id == m.Sample.MSG_ID:
            sample = message_class(frame.msg_id).unpack(frame.payload)
            raw[sample.sample] = sample  # type: ignore[attr-defined]
    checked = 0
    for msg in iter_messages(path, {"/agent/SAMPLE", "/agent/EPISODE_START", "/agent/EPISODE_END"}):
        body = json.loads(msg.data)
        for name in float32_fields(msg.topic):
            value = body[name]
            if value is None:
                continue  # NaN or infinity: null, as always
            shortest = float(str(np.float32(value)))
            assert value == shortest, (msg.topic, name, value, shortest)  # no widening noise
            if msg.topic == "/agent/SAMPLE":
                assert np.float32(value) == np.float32(getattr(raw[body["sample"]], name))  # the agent's float32
            checked += 1
    assert checked > 1000
    # as the file holds them: no more digits than a float32 has (9 significant), where widening wrote 16-17
    durations = [re.search(rb'"duration_s":([^,}]+)', msg.data) for msg in iter_messages(path, {"/agent/EPISODE_END"})]
    assert durations and all(d is not None and len(d.group(1).lstrip(b"-").replace(b".", b"")) <= 9 for d in durations)


def test_every_reader_gives_an_old_recording_the_same_figures(tmp_path: Path) -> None:
    (new,) = record_onboard(tmp_path / "new.mcap", "paper", "python", seed=2, episodes=3)
    old = tmp_path / "old.mcap"
    assert _widened(new, old) > 1000
    widened = [json.loads(msg.data)["duration_s"] for msg in iter_messages(old, {"/agent/EPISODE_END"})]
    assert any(len(repr(v)) > 12 for v in widened)  # the old file does carry the noise

    # dive log info: both readers, and its JSON as a script reads it
    assert summarize(old).episodes == summarize(new).episodes == summarize_stream(old).episodes
    runner = CliRunner()
    infos = []
    for path in (new, old):
        done = runner.invoke(app, ["log", "info", str(path), "--json"])
        assert done.exit_code == 0, done.output
        infos.append([e for e in json.loads(done.output)["episodes"]])
    assert infos[0] == infos[1] and all(math.isfinite(e["duration_s"]) for e in infos[0])

    # open_recording's tables hold the JSON's numbers as float64: the same float32 in both (the new file's without
    # the noise); the Parquet export, float32 columns for F32 fields, is the same table for both
    tables = [open_recording(p) for p in (new, old)]
    for table in ("episodes", "samples"):
        a, b = (getattr(rec, table)() for rec in tables)
        assert a.dtype == b.dtype and len(a) == len(b)
        for name in a.dtype.names:
            same = a[name].astype(np.float32) if a[name].dtype.kind == "f" else a[name], \
                b[name].astype(np.float32) if b[name].dtype.kind == "f" else b[name]
            assert np.array_equal(*same, equal_nan=a[name].dtype.kind == "f"), (table, name)
    written = []
    for rec, name in zip(tables, ("new", "old"), strict=True):
        export_parquet(rec, name, tmp_path / name)
        written.append({p.name.removeprefix(name): pq.read_table(p).to_pylist()
                        for p in sorted((tmp_path / name).glob("*.parquet"))})
    assert written[0].keys() == written[1].keys() and written[0] == written[1]
