"""Depth is drawn downward everywhere: the time series plots z up = -depth, the heatmaps put deeper cells lower."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from groundstation.cli.app import app
from protocol import messages as m
from tests.groundstation.rrd_readback import blueprint_values, component_rows
from tests.groundstation.synthetic_agent import Traffic, generate, record


@pytest.fixture(scope="module")
def replayed(tmp_path_factory: pytest.TempPathFactory) -> tuple[Traffic, Path]:
    traffic = generate(duration_s=30.0)
    directory = tmp_path_factory.mktemp("depth")
    recording = record(traffic, directory / "depth.mcap")
    out = directory / "replay.rrd"
    done = CliRunner().invoke(app, ["replay", str(recording), "--rrd", str(out)])
    assert done.exit_code == 0, done.output
    return traffic, out


def _scalars(path: Path, entity: str) -> np.ndarray:
    return np.array([row["Scalars:scalars"][0] for row in component_rows(path, entity) if "Scalars:scalars" in row])


def test_the_depth_panel_plots_minus_depth_so_deeper_is_lower(replayed: tuple[Traffic, Path]) -> None:
    traffic, out = replayed
    depths = np.array([r.message.depth_m for r in traffic.frames if isinstance(r.message, m.Sample)])
    z_up = _scalars(out, "/depth/z_up_m")
    np.testing.assert_allclose(z_up, -depths.astype(np.float32), rtol=1e-6)
    target = _scalars(out, "/depth/target_z_up_m")
    top, bottom = _scalars(out, "/depth/region_top_z_up_m"), _scalars(out, "/depth/region_bottom_z_up_m")
    assert np.allclose(target, -0.5) and np.all(bottom < target) and np.all(target < top)  # bottom drawn lowest
    names = [name for row in component_rows(out, "/depth/z_up_m") for name in row.get("SeriesLines:names") or []]
    assert "z up = -depth [m]" in names


def test_the_heatmaps_agree_deeper_cells_sit_lower(replayed: tuple[Traffic, Path]) -> None:
    """The 2D view's y grows downward: a deeper sample's cell has a larger y, as its z up is smaller."""
    _traffic, out = replayed
    z_up = _scalars(out, "/depth/z_up_m")
    cells = component_rows(out, "/value_function/current_cell")
    cell_y = np.array([row["Boxes2D:centers"][0][1] for row in cells if "Boxes2D:centers" in row])
    assert len(cell_y) == len(z_up)
    order = np.argsort(-z_up, kind="stable")  # shallow to deep
    assert np.all(np.diff(cell_y[order]) >= 0) and cell_y[order][-1] > cell_y[order][0]


def test_the_panel_names_say_which_way_is_down(replayed: tuple[Traffic, Path]) -> None:
    names = [name for names in blueprint_values(replayed[1], "ViewBlueprint:display_name") for name in names]
    assert "Depth drawn downward (z up = -depth) [m]" in names, names
    assert sum("depth down" in name for name in names) >= 2  # the value and policy heatmaps
