"""Legends that are legends (issue 40 item 2): every plot of several series shows Rerun's legend, each series named
(modes and actions by their names, not numbers), and no title names a colour; read back from a .rrd."""

from __future__ import annotations

from pathlib import Path

import pytest
import rerun.chunk as rrc

from groundstation.view.rerun_sink import RerunView, ViewConfig
from tests.groundstation.rrd_readback import blueprint_values
from tests.groundstation.synthetic_agent import generate, play_session

COLOUR_WORDS = ("blue", "green", "grey", "red", "amber", "orange")


@pytest.fixture(scope="module")
def live_rrd(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("legends") / "live.rrd"
    with RerunView.open(ViewConfig(rrd=out)) as view:
        play_session(generate(duration_s=20.0), [view])
    return out


def _static_names(path: Path) -> dict[str, list[str]]:
    """Entity -> the series names logged for it once (SeriesLines / SeriesPoints names)."""
    names: dict[str, list[str]] = {}
    for chunk in rrc.RrdReader(path).stream().collect().stream():
        if not chunk.is_static:
            continue
        batch = chunk.to_record_batch()
        for column in ("SeriesLines:names", "SeriesPoints:names"):
            if column in batch.schema.names:
                names[chunk.entity_path.removeprefix("/")] = batch.column(column)[0].as_py()
    return names


def test_plots_of_several_series_show_the_legend(live_rrd: Path) -> None:
    """In each blueprint sent: every plot has a PlotLegend; shown but for the one-series plots (reward, battery,
    the bar chart), whose titles say what they are."""
    reader = rrc.RrdReader(live_rrd)
    stores = list(reader.blueprints())
    assert stores
    for store in stores:
        legends: dict[str, object] = {}
        titles: dict[str, str] = {}
        for chunk in reader.stream(store=store).collect().stream():
            batch = chunk.to_record_batch()
            if "PlotLegend:visible" in batch.schema.names:
                legends[chunk.entity_path.removesuffix("/PlotLegend")] = batch.column("PlotLegend:visible")[0].as_py()
            if "ViewBlueprint:display_name" in batch.schema.names:
                titles[chunk.entity_path] = batch.column("ViewBlueprint:display_name")[0].as_py()[0]
        shown = sorted(titles[view] for view, visible in legends.items() if visible == [True])
        assert shown == ["Actuator [deg]", "Depth drawn downward (z up = -depth) [m]",
                         "Episode durations [s] over agent time", "Learner's action", "Link", "Mode",
                         "Velocity [m/s]"], shown
        assert len(legends) == 10  # nine time series and the learning curve's bar chart


def test_series_have_names_modes_and_actions_their_labels_titles_no_colours(live_rrd: Path) -> None:
    names = _static_names(live_rrd)
    assert names["mode/learning"] == ["LEARNING"] and names["mode/paused"] == ["PAUSED"]
    assert names["action/decrease_volume"] == ["less volume (a1)"]
    assert names["action/increase_volume"] == ["more volume (a2)"]
    assert names["depth/target_z_up_m"] == ["target z up [m]"]
    titles = [name for names in blueprint_values(live_rrd, "ViewBlueprint:display_name") for name in names]
    assert titles and not [t for t in titles if any(word in t.lower() for word in COLOUR_WORDS)], titles
    logged = {chunk.entity_path.removeprefix("/") for chunk in rrc.RrdReader(live_rrd).stream().collect().stream()
              if not chunk.is_static}
    assert {"mode/learning", "action/decrease_volume", "action/increase_volume"} <= logged  # the data went there
