"""`dive dump --png`: the value function and the policy drawn over the learner's grid, read back as images."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from matplotlib.image import imread
from typer.testing import CliRunner

from groundstation.cli.app import app
from groundstation.view.dump_plot import write_dump_png
from groundstation.view.heatmap import POLICY_COLOURS, UNTRIED, dump_grid, value_palette
from protocol import DumpKind


def _has_colour(image: np.ndarray, rgb: np.ndarray, tolerance: float = 0.02) -> bool:
    return bool(np.any(np.all(np.abs(image[..., :3] - rgb) < tolerance, axis=-1)))


def test_values_over_two_actuator_bins_show_the_palettes_ends(tmp_path: Path) -> None:
    grid = dump_grid(4 * 5 * 2 + 1, 0.4, 0.1, 0.04, z_cells=4, zdot_cells=5)
    assert grid is not None and (grid.z_cells, grid.zdot_cells, grid.blocks) == (4, 5, 2)
    values = np.append(np.linspace(-9.0, 0.0, 40), -20.0).astype(np.float32)  # the terminal state is not drawn
    path = tmp_path / "values.png"
    write_dump_png(path, DumpKind.VALUES, values, grid, episode=7)
    image = imread(path)
    assert image.shape[0] > 200 and image.shape[1] > image.shape[0]  # two panels side by side, and a colour bar
    palette = value_palette()
    assert _has_colour(image, palette[0]) and _has_colour(image, palette[-1])


def test_a_dump_shorter_than_one_row_has_no_grid() -> None:
    assert dump_grid(5, 0.4, 0.1, 0.04, z_cells=4, zdot_cells=5) is None


def test_dive_dump_png_against_the_builtin_agent(tmp_path: Path) -> None:
    path = tmp_path / "policy.png"
    done = CliRunner().invoke(app, ["dump", "sim://?speed=max&seed=1", "--kind", "policy", "--png", str(path)])
    assert done.exit_code == 0, done.stderr
    assert done.stdout.strip() == f"{path}: policy of episode 0 over 10 x 10 cells"
    image = imread(path)
    # A fresh agent has left no state yet: every cell untried; the legend shows the actions' colours too.
    for colour in (UNTRIED[0], *(c for c, _ in POLICY_COLOURS.values())):
        assert _has_colour(image, np.array(colour) / 255), colour


def test_png_refuses_what_it_cannot_draw_and_never_overwrites_a_recording(tmp_path: Path) -> None:
    q = CliRunner().invoke(app, ["dump", "sim://", "--kind", "q", "--png", str(tmp_path / "q.png")])
    assert q.exit_code == 2 and "--png draws --kind values or policy" in q.stderr
    recording = tmp_path / "run.mcap"
    recording.write_bytes(b"\x89MCAP0\r\n" + b"kept")
    onto = CliRunner().invoke(app, ["dump", "sim://", "--png", str(recording)])
    assert onto.exit_code == 1 and "is an existing recording" in onto.stderr
    assert recording.read_bytes() == b"\x89MCAP0\r\nkept"
    nowhere = CliRunner().invoke(app, ["dump", "sim://", "--png", str(tmp_path / "nowhere" / "v.png")])
    assert nowhere.exit_code == 1 and "there is no folder" in nowhere.stderr
