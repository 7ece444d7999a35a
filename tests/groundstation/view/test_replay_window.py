"""`dive replay --from/--to` in agent time, the timeline the viewer shows; a bad window leaves no partial .rrd."""

from __future__ import annotations

from pathlib import Path

import pytest
from typer.testing import CliRunner

from groundstation.cli.app import app
from tests.groundstation.synthetic_agent import START_NS, Traffic, generate, record

SPEED = 100  # the agent's clock runs 100x the host's, as with `dive run --speed 100`


@pytest.fixture(scope="module")
def fast_recording(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, int]:
    """150 s of agent time recorded in 1.5 s of host time."""
    traffic = generate(duration_s=150.0)
    squeezed = Traffic([r._replace(host_time_ns=START_NS + (r.host_time_ns - START_NS) // SPEED)
                        for r in traffic.frames],
                       [(START_NS + (t - START_NS) // SPEED, body) for t, body in traffic.link])
    return record(squeezed, tmp_path_factory.mktemp("rec") / "fast.mcap"), len(traffic.frames)


def test_a_one_minute_window_is_a_minute_of_agent_time(fast_recording: tuple[Path, int], tmp_path: Path) -> None:
    path, total = fast_recording
    out = tmp_path / "minute.rrd"
    done = CliRunner().invoke(app, ["replay", str(path), "--from", "60s", "--to", "2m", "--rrd", str(out)])
    assert done.exit_code == 0, done.output
    frames = int(done.stdout.split(": ")[1].split()[0])
    assert 601 <= frames < total / 2  # the 601 samples from 60.0 to 120.0 s at 10 Hz, dumps and events beside them


@pytest.mark.parametrize(("window", "why", "code"), [
    (["--from", "2m", "--to", "1m"], "--from 120 s is after --to 60 s", 2),  # bad usage
    (["--from", "12", "--to", "3"], "--from episode 12 is after", 2),
    (["--from", "2h"], "holds no agent frames", 1),  # a valid window with nothing in it
])
def test_a_reversed_or_empty_window_is_one_line_and_no_rrd(fast_recording: tuple[Path, int], tmp_path: Path,
                                                          window: list[str], why: str, code: int) -> None:
    out = tmp_path / "none.rrd"
    done = CliRunner().invoke(app, ["replay", str(fast_recording[0]), *window, "--rrd", str(out)])
    assert done.exit_code == code
    lines = [line for line in done.stderr.splitlines() if line.strip()]
    assert len(lines) == 1 and why in lines[0], done.stderr
    assert not out.exists()


def test_a_window_opens_on_the_heatmaps_and_the_learning_curve_so_far(fast_recording: tuple[Path, int],
                                                                     tmp_path: Path) -> None:
    """`--from` past the first episodes: the latest dumps and the curve before the window are in the .rrd at times
    before the window's first sample, so the viewer opening at the window's start shows them (issue 40: the
    heatmaps and the learning curve were empty for minutes)."""
    import pyarrow as pa
    import rerun.chunk as rrc

    path, _ = fast_recording
    out = tmp_path / "window.rrd"
    done = CliRunner().invoke(app, ["replay", str(path), "--from", "100s", "--rrd", str(out)])
    assert done.exit_code == 0, done.output
    first: dict[str, float] = {}
    for chunk in rrc.RrdReader(out).stream().collect().stream():
        if chunk.is_static:
            continue
        times = chunk.to_record_batch().column("agent_time").cast(pa.int64()).to_pylist()  # ns
        entity = chunk.entity_path.removeprefix("/")
        earliest = min(times) / 1e9
        first[entity] = min(first.get(entity, earliest), earliest)
    window_s = first["depth/z_up_m"]
    assert window_s == pytest.approx(100.0, abs=0.2)
    for entity in ("policy/image", "value_function/image", "learning_curve_by_episode/duration_s",
                   "learning_curve/duration_s"):
        assert first[entity] < window_s, (entity, first.get(entity))
