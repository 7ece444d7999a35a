"""No legend box over the data: every plot hides its legend and its title names each series, read back from a .rrd."""

from __future__ import annotations

from pathlib import Path

import pytest
import rerun.chunk as rrc

from groundstation.view.rerun_sink import SERIES_COLOURS, RerunView, ViewConfig
from tests.groundstation.rrd_readback import blueprint_values
from tests.groundstation.synthetic_agent import generate, play_session

COLOUR_NAMES = {(40, 120, 220): "blue", (60, 180, 75): "green", (150, 150, 150): "grey", (230, 60, 60): "red",
                (200, 160, 40): "amber", (230, 120, 30): "orange", (40, 200, 120): "green"}


@pytest.fixture(scope="module")
def live_rrd(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("legends") / "live.rrd"
    with RerunView.open(ViewConfig(rrd=out)) as view:
        play_session(generate(duration_s=20.0), [view])
    return out


def test_every_plot_hides_its_legend(live_rrd: Path) -> None:
    """In each blueprint sent: every time series and bar chart view has a PlotLegend property, and it is hidden."""
    reader = rrc.RrdReader(live_rrd)
    stores = list(reader.blueprints())
    assert stores
    for store in stores:
        plots: set[str] = set()
        legends: dict[str, object] = {}
        for chunk in reader.stream(store=store).collect().stream():
            batch = chunk.to_record_batch()
            if "ViewBlueprint:class_identifier" in batch.schema.names:
                if batch.column("ViewBlueprint:class_identifier")[0].as_py() in (["TimeSeries"], ["BarChart"]):
                    plots.add(chunk.entity_path)
            if "PlotLegend:visible" in batch.schema.names:
                legends[chunk.entity_path.removesuffix("/PlotLegend")] = batch.column("PlotLegend:visible")[0].as_py()
        assert len(plots) == 10  # nine time series and the learning curve's bar chart
        assert legends == dict.fromkeys(plots, [False])


def test_multi_series_titles_name_each_series_by_its_colour(live_rrd: Path) -> None:
    names = [name for names in blueprint_values(live_rrd, "ViewBlueprint:display_name") for name in names]
    for origin, start in (("depth", "Depth"), ("velocity", "Velocity"), ("actuator", "Actuator"), ("link", "Link"),
                          ("learning_curve", "Episode durations")):
        title = next(name for name in names if name.startswith(start))
        colours = {COLOUR_NAMES[rgb] for path, rgb in SERIES_COLOURS.items() if path.startswith(f"{origin}/")}
        assert colours and all(colour in title for colour in colours), (origin, title)
