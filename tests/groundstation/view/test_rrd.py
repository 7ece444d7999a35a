"""The live view and the replay write the same entities: .rrd files read back with Rerun's own API."""

from __future__ import annotations

from pathlib import Path

import pytest
from mcap.reader import make_reader
from typer.testing import CliRunner

from groundstation.cli.app import app
from groundstation.view.rerun_sink import RerunView, ViewConfig
from protocol import messages as m
from tests.groundstation.rrd_readback import rows_per_entity, timelines
from tests.groundstation.synthetic_agent import Traffic, generate, record


@pytest.fixture(scope="module")
def traffic() -> Traffic:
    return generate(duration_s=120.0, backfill_every=97)  # two minutes: a dozen episodes and their dumps


@pytest.fixture(scope="module")
def live_run(traffic: Traffic, tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    """What `dive run --rrd` does: the recorder and the view listener side by side on one session's traffic."""
    directory = tmp_path_factory.mktemp("run")
    with RerunView.open(ViewConfig(rrd=directory / "live.rrd")) as view:
        record(traffic, directory / "session.mcap", [view])
    return directory / "session.mcap", directory / "live.rrd"


@pytest.fixture(scope="module")
def recording(live_run: tuple[Path, Path]) -> Path:
    return live_run[0]


def _mcap_samples(path: Path) -> int:
    with path.open("rb") as stream:
        return sum(1 for _s, _c, msg in make_reader(stream).iter_messages(topics=["/raw/rx"]) if msg.data[4] == 0x20)


def test_live_and_replayed_rrd_hold_the_same_entities_with_every_sample(
    traffic: Traffic, live_run: tuple[Path, Path], tmp_path: Path
) -> None:
    recording, live_rrd = live_run
    live = rows_per_entity(live_rrd)
    result = CliRunner().invoke(app, ["replay", str(recording), "--rrd", str(tmp_path / "replay.rrd")])
    assert result.exit_code == 0, result.output
    replayed = rows_per_entity(tmp_path / "replay.rrd")

    samples = _mcap_samples(recording)
    assert samples == traffic.samples == 1200
    assert set(live) == set(replayed)
    assert live == replayed  # same rows, not just the same names
    assert replayed["/depth/z_up_m"] == samples
    for entity in ("/velocity/velocity_mps", "/actuator/actuator_deg", "/reward/reward", "/depth/target_z_up_m",
                   "/value_function/image", "/policy/image", "/value_function/current_cell",
                   "/learning_curve/duration_s", "/learning_curve/moving_average_s", "/link/loss_ratio",
                   "/link/rtt_s", "/link/backfilled_samples", "/log/agent", "/log/events",
                   "/depth/episode_start_z_up_m", "/depth/episode_failure_z_up_m"):
        assert replayed[entity] > 0, entity
    episodes = sum(isinstance(r.message, m.EpisodeEnd) for r in traffic.frames)
    assert replayed["/learning_curve/duration_s"] == episodes
    assert timelines(tmp_path / "replay.rrd", "/depth/z_up_m") == {"agent_time", "host_time", "episode", "step"}


def test_replay_at_a_finite_speed_shows_the_same_rows_as_max(recording: Path, tmp_path: Path) -> None:
    fast = CliRunner().invoke(app, ["replay", str(recording), "--speed", "max", "--rrd", str(tmp_path / "a.rrd")])
    paced = CliRunner().invoke(app, ["replay", str(recording), "--speed", "2000x", "--rrd", str(tmp_path / "b.rrd")])
    assert fast.exit_code == 0 and paced.exit_code == 0, paced.output
    assert rows_per_entity(tmp_path / "a.rrd") == rows_per_entity(tmp_path / "b.rrd")


def test_an_episode_range_shows_only_those_episodes(traffic: Traffic, recording: Path, tmp_path: Path) -> None:
    out = tmp_path / "range.rrd"
    result = CliRunner().invoke(app, ["replay", str(recording), "--from", "3", "--to", "5", "--rrd", str(out)])
    assert result.exit_code == 0, result.output
    wanted = sum(isinstance(r.message, m.Sample) and 3 <= r.message.episode <= 5 for r in traffic.frames)
    assert rows_per_entity(out)["/depth/z_up_m"] == wanted
    # episodes 3 to 5, and the curve so far (episodes 1 and 2) the window opens on
    assert rows_per_entity(out)["/learning_curve/duration_s"] == 5


def test_a_time_range_shows_only_that_window(recording: Path, tmp_path: Path) -> None:
    out = tmp_path / "window.rrd"
    result = CliRunner().invoke(app, ["replay", str(recording), "--from", "30s", "--to", "1m", "--rrd", str(out)])
    assert result.exit_code == 0, result.output
    assert rows_per_entity(out)["/depth/z_up_m"] == 301  # 10 Hz from 30.0 s to 60.0 s inclusive
