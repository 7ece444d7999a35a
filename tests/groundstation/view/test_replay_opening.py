"""`dive replay` opens at the first episode: its blueprint pauses the time panel on the first episode, read back."""

from __future__ import annotations

from pathlib import Path

import pytest
from typer.testing import CliRunner

from groundstation.cli.app import app
from protocol import messages as m
from tests.groundstation.rrd_readback import blueprint_values
from tests.groundstation.synthetic_agent import Traffic, generate, record


@pytest.fixture(scope="module")
def traffic() -> Traffic:
    return generate(duration_s=40.0)


@pytest.fixture(scope="module")
def recording(traffic: Traffic, tmp_path_factory: pytest.TempPathFactory) -> Path:
    return record(traffic, tmp_path_factory.mktemp("rec") / "opening.mcap")


def _first_episode_ns(traffic: Traffic) -> tuple[int, int]:
    starts = [r.message.t_us * 1000 for r in traffic.frames if isinstance(r.message, m.EpisodeStart)]
    return starts[0], starts[1]


@pytest.mark.parametrize("speed", ["max", "4000x"])
def test_a_replay_opens_paused_on_the_first_episode(traffic: Traffic, recording: Path, tmp_path: Path,
                                                   speed: str) -> None:
    out = tmp_path / "replay.rrd"
    done = CliRunner().invoke(app, ["replay", str(recording), "--speed", speed, "--rrd", str(out)])
    assert done.exit_code == 0, done.output
    states = blueprint_values(out, "TimePanelBlueprint:play_state")
    assert states and all(state == [1] for state in states)  # PlayState.Paused: the viewer starts at the start
    selections = blueprint_values(out, "TimePanelBlueprint:time_selection")
    start_ns, next_ns = _first_episode_ns(traffic)
    assert selections[-1][0]["min"] == start_ns
    assert start_ns < selections[-1][0]["max"] <= next_ns


def test_a_live_view_keeps_following(recording: Path, tmp_path: Path) -> None:
    from groundstation.view.rerun_sink import RerunView, ViewConfig
    from tests.groundstation.synthetic_agent import play_session

    out = tmp_path / "live.rrd"
    with RerunView.open(ViewConfig(rrd=out)) as view:
        play_session(generate(duration_s=20.0), [view])
    assert blueprint_values(out, "TimePanelBlueprint:play_state") == []  # the viewer's own default: follow
