"""The learning curve by episode number: a bar chart per episode end, on the main timeline, read back from the .rrd."""

from __future__ import annotations

from pathlib import Path

import pytest
from typer.testing import CliRunner

from groundstation.cli.app import app
from protocol import EndReason
from protocol import messages as m
from tests.groundstation.rrd_readback import blueprint_values, component_rows, timelines
from tests.groundstation.synthetic_agent import Traffic, generate, record

ENTITY = "/learning_curve_by_episode/duration_s"


@pytest.fixture(scope="module")
def replayed(tmp_path_factory: pytest.TempPathFactory) -> tuple[Traffic, Path]:
    traffic = generate(duration_s=60.0)
    directory = tmp_path_factory.mktemp("curve")
    out = directory / "replay.rrd"
    done = CliRunner().invoke(app, ["replay", str(record(traffic, directory / "curve.mcap")), "--rrd", str(out)])
    assert done.exit_code == 0, done.output
    return traffic, out


def test_each_episode_end_logs_the_whole_curve_by_episode_number(replayed: tuple[Traffic, Path]) -> None:
    traffic, out = replayed
    ends = [r.message for r in traffic.frames
            if isinstance(r.message, m.EpisodeEnd) and r.message.reason != EndReason.ABORTED]
    charts = [row for row in component_rows(out, ENTITY) if "BarChart:values" in row]
    assert len(charts) == len(ends) > 3
    last = charts[-1]
    assert last["BarChart:abscissa"][0]["buffer"] == [float(e.episode) for e in ends]
    assert last["BarChart:values"][0]["buffer"] == pytest.approx([e.duration_s for e in ends], rel=1e-6)
    assert len(charts[0]["BarChart:values"][0]["buffer"]) == 1  # the curve as it stood at the first episode's end


def test_the_curve_sits_on_the_main_timeline_in_its_own_panel(replayed: tuple[Traffic, Path]) -> None:
    _traffic, out = replayed
    assert "agent_time" in timelines(out, ENTITY)  # shown by the time panel's own timeline, no switch to `episode`
    names = [name for names in blueprint_values(out, "ViewBlueprint:display_name") for name in names]
    assert "Learning curve: duration [s] by episode number" in names
