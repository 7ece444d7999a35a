"""Split recordings (`dive run --split-mb`): parts the size asked for on disk, named in time order, each opening on
its own (log info, replay, export), and replayed together as one timeline of agent time."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from groundstation.cli.app import app
from groundstation.mcap_io import RecordingContents, iter_messages
from groundstation.recording.files import expand
from groundstation.recording.recorder import Recorder, RecorderConfig
from groundstation.recording.tables import open_recording
from groundstation.view import replay as rp
from groundstation.view import replay_convert as rc
from groundstation.view import replay_window as rw
from groundstation.view.replay_items import read_parts
from protocol import Frame
from protocol import messages as m
from protocol.frame import build_inner
from tests.groundstation.synthetic_agent import Traffic, generate, play_session

SPLIT_BYTES = 150_000
GRID = {"z_cells": 10.0, "zdot_cells": 10.0, "act_bins": 1.0, "target_depth_m": 0.5}


def _record(traffic: Traffic, config: RecorderConfig) -> list[Path]:
    recorder = Recorder(config)
    recorder.set_parameters(GRID)
    try:
        play_session(traffic, [recorder])
    finally:
        recorder.close()
    return recorder.paths


@pytest.fixture(scope="module")
def traffic() -> Traffic:
    return generate(duration_s=1500.0)  # 15,000 samples, ~2.7 MB on disk: 18 parts of 150 kB


@pytest.fixture(scope="module")
def parts(traffic: Traffic, tmp_path_factory: pytest.TempPathFactory) -> list[Path]:
    return _record(traffic, RecorderConfig(directory=tmp_path_factory.mktemp("split"), split_bytes=SPLIT_BYTES))


@pytest.fixture(scope="module")
def whole(traffic: Traffic, tmp_path_factory: pytest.TempPathFactory) -> Path:
    return _record(traffic, RecorderConfig(directory=tmp_path_factory.mktemp("whole")))[0]


def _first_sample(path: Path) -> int:
    return next(json.loads(msg.data)["sample"] for msg in iter_messages(path, {"/agent/SAMPLE"}))


def test_parts_are_the_size_asked_for_on_disk(parts: list[Path]) -> None:
    sizes = [p.stat().st_size for p in parts]
    assert len(parts) >= 10, sizes
    # Counting message bytes before compression (the old way) made 150 kB parts of ~20 kB on disk.
    assert all(0.85 * SPLIT_BYTES <= size <= 1.15 * SPLIT_BYTES for size in sizes[:-1]), sizes
    assert sizes[-1] <= 1.15 * SPLIT_BYTES


def test_parts_sort_in_time_order(parts: list[Path]) -> None:
    names = [p.name for p in parts]
    assert names[0].endswith("-part001.mcap") and names[9].endswith("-part010.mcap")
    by_name = sorted(parts[0].parent.glob("*.mcap"))
    assert by_name == parts  # ls and a glob list them as they were written
    firsts = [_first_sample(p) for p in by_name]
    assert firsts == sorted(firsts)


def test_the_parts_together_hold_the_whole_recording(parts: list[Path], whole: Path) -> None:
    split, one = open_recording(parts[0].parent), open_recording(whole)
    assert (split.samples()["sample"] == one.samples()["sample"]).all()
    assert len(split.episodes()) == len(one.episodes())


def test_each_part_opens_on_its_own(parts: list[Path], tmp_path: Path) -> None:
    runner = CliRunner()
    for index in (1, len(parts) // 2):
        part = parts[index]
        info = runner.invoke(app, ["log", "info", str(part), "--json"])
        assert info.exit_code == 0, info.output
        summary = json.loads(info.stdout)
        assert summary["agent"]["node_id"] == "00000007" and summary["parameters"]["zdot_cells"] == 10
        held = summary["topics"]["/agent/SAMPLE"]
        assert summary["part"] == index + 1 and held > 100
        text = runner.invoke(app, ["log", "info", str(part)]).stdout
        assert f"part {index + 1} of a split recording" in text
        rrd = tmp_path / f"{part.stem}.rrd"
        shown = runner.invoke(app, ["replay", str(part), "--rrd", str(rrd)])
        assert shown.exit_code == 0 and rrd.stat().st_size > 0, shown.output
        csv = tmp_path / f"{part.stem}.csv"
        exported = runner.invoke(app, ["log", "export", str(part), "--out", str(csv)])
        assert exported.exit_code == 0, exported.output
        assert len(csv.read_text().splitlines()) - 1 == held


def test_a_part_carries_the_parameter_table_for_the_view(parts: list[Path]) -> None:
    """A later part holds no PARAM_VALUE: the heatmaps take the grid from its header (zdot_cells 10 columns)."""
    later = rp.plan([parts[3]])
    assert {"zdot_cells", "z_cells"} <= set(later.header["parameters"][-1])
    batch, _ = rc.convert_parts(later, [RecordingContents()])
    assert any(rows.values and rows.values[0].shape[1] == 10 for path, rows in batch.items() if path.endswith("image"))


def test_the_folder_replays_as_the_unsplit_recording(parts: list[Path], whole: Path) -> None:
    split, _ = rc.convert_parts(rp.plan(expand([parts[0].parent])), [RecordingContents() for _ in parts])
    one, _ = rc.convert_recording(whole, RecordingContents())
    assert {path: len(rows.values) for path, rows in split.items()} == \
        {path: len(rows.values) for path, rows in one.items()}
    assert split["depth/z_up_m"].agent_time_s == one["depth/z_up_m"].agent_time_s


def test_a_window_across_parts_is_one_timeline(parts: list[Path], tmp_path: Path) -> None:
    plan = rp.plan(list(reversed(parts)))  # given in any order: played by part number
    assert plan.files == parts
    items = rw.select(read_parts(plan, [RecordingContents() for _ in parts]), rw.parse_bound("100s"),
                      rw.parse_bound("400s"))
    times = [item.agent_time_s for item in items if item.agent_time_s is not None and not item.before]
    assert times[0] == pytest.approx(100.0) and times[-1] == pytest.approx(400.0)
    assert all(b >= a for a, b in zip(times, times[1:], strict=False))
    assert _first_sample(parts[1]) < 3000  # the window spans several parts
    done = CliRunner().invoke(app, ["replay", str(parts[0].parent), "--from", "100s", "--to", "400s",
                                    "--rrd", str(tmp_path / "w.rrd")])
    assert done.exit_code == 0, done.output


def test_a_missing_part_is_said(parts: list[Path], tmp_path: Path) -> None:
    done = CliRunner().invoke(app, ["replay", str(parts[0]), str(parts[2]), "--rrd", str(tmp_path / "gap.rrd")])
    assert done.exit_code == 0
    assert "part(s) 2 of" in done.stderr


@pytest.mark.parametrize(("given", "why", "code"), [
    ("two recordings", "hold 2 recordings", 2),
    ("empty folder", "no .mcap recordings in", 1),
    ("not mcap", "is not an MCAP recording", 1),
    ("missing", "no such recording", 1),
])
def test_bad_input_is_one_line_and_no_rrd(parts: list[Path], whole: Path, tmp_path: Path, given: str, why: str,
                                          code: int) -> None:
    (tmp_path / "empty").mkdir()
    (tmp_path / "notes.mcap").write_text("not a recording\n")
    extra = {"two recordings": whole, "empty folder": tmp_path / "empty", "not mcap": tmp_path / "notes.mcap",
             "missing": tmp_path / "gone.mcap"}[given]
    out = tmp_path / "none.rrd"
    done = CliRunner().invoke(app, ["replay", str(parts[0]), str(parts[1]), str(extra), "--rrd", str(out)])
    assert done.exit_code == code
    lines = [line for line in done.stderr.splitlines() if line.strip()]
    assert len(lines) == 1 and why in lines[0], done.stderr
    assert not out.exists()


def test_two_recorders_in_one_folder_keep_their_parts_apart(tmp_path: Path) -> None:
    """The run and a `dive record` of the same agent in the same second: two sets of parts, never interleaved."""
    traffic = generate(duration_s=200.0)
    config = RecorderConfig(directory=tmp_path, split_bytes=40_000)
    recorders = [Recorder(config), Recorder(config)]
    recorders[1]._stamp = recorders[0]._stamp  # noqa: SLF001 the same second, whenever the test runs
    try:
        play_session(traffic, recorders)
    finally:
        for recorder in recorders:
            recorder.close()
    first, second = (recorder.paths for recorder in recorders)
    assert len(first) >= 2 and len(first) == len(second)
    assert second[0].name == first[0].name.replace("-part001", "-2-part001")
    assert all(p.name.startswith(second[0].name.removesuffix("-part001.mcap")) for p in second)
    assert len(rp.plan(second).files) == len(second)  # the second's parts are one recording


def test_the_parts_export_as_one_recording(parts: list[Path], whole: Path, tmp_path: Path) -> None:
    """`dive log export FOLDER`: one file for the parts of one recording, episodes across parts kept whole."""
    runner = CliRunner()
    done = runner.invoke(app, ["log", "export", str(parts[0].parent), "--format", "npz"])
    assert done.exit_code == 0, done.output
    [written] = list(parts[0].parent.glob("*.npz"))
    assert written.name == parts[0].name.replace("-part001.mcap", ".npz")
    one = runner.invoke(app, ["log", "export", str(whole), "--format", "npz", "--out", str(tmp_path / "one.npz")])
    assert one.exit_code == 0, one.output
    split, single = np.load(written), np.load(tmp_path / "one.npz")
    assert len(split["episode"]) == len(single["episode"]) > 1000
    assert (split["next_state"] == single["next_state"]).all()


def test_a_reboot_inside_a_later_part_is_a_new_boot(tmp_path: Path) -> None:
    """A later part has no HELLO of its own: its header names the boot it begins in, so the agent's reboot inside
    it (a HELLO with a new boot id, sample indices from 0 again) is told apart, not spliced into one boot."""
    before, after = generate(duration_s=300.0), generate(duration_s=100.0)
    shift_ns = before.frames[-1].host_time_ns + 1_000_000_000 - after.frames[0].host_time_ns
    rebooted = []
    for received in after.frames:
        frame = received.frame
        if isinstance(frame.message, m.Hello):
            hello = dataclasses.replace(frame.message, boot_id=12)
            frame = Frame(frame.flags, frame.seq, frame.msg_id, hello, build_inner(frame.flags, frame.seq,
                                                                                   frame.msg_id, hello.pack()))
        rebooted.append(received._replace(frame=frame, host_time_ns=received.host_time_ns + shift_ns))
    paths = _record(Traffic([*before.frames, *rebooted], []), RecorderConfig(directory=tmp_path, split_bytes=40_000))
    [holding] = [p for p in paths[1:] if any(True for _ in iter_messages(p, {"/agent/HELLO"}))]
    done = CliRunner().invoke(app, ["log", "info", str(holding), "--json"])
    assert done.exit_code == 0, done.output
    boots = [b["boot"] for b in json.loads(done.stdout)["boots"]]
    assert boots == [1, 2]  # without the header the part's first boot was unknown and the reboot went unseen
    assert sorted(set(open_recording(*paths).samples()["boot"].tolist())) == [1, 2]
