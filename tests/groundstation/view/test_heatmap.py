"""The heatmaps answer what a user asks of them: which depth and velocity a cell is, what its colour means.

Each test writes a recording with the view (the live listener, or `dive replay`) and reads it back with Rerun.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from groundstation.cli.app import app
from groundstation.session.events import Received
from groundstation.view.rerun_sink import RerunView, ViewConfig
from protocol import DumpKind, EndReason, Frame, Message, Mode, ParamType, definitions_hash
from protocol import messages as m
from protocol.frame import build_inner
from tests.groundstation.rrd_readback import blueprint_values, latest
from tests.groundstation.synthetic_agent import START_NS, Traffic, record

# A grid unlike the defaults: 4 depth cells x 5 velocity cells, around 0.8 m, +-0.2 m, +-0.1 m/s.
TARGET_M, Z_TOL_M, ZDOT_TOL_MPS, Z_CELLS, ZDOT_CELLS = 0.8, 0.2, 0.1, 4, 5
STATES = Z_CELLS * ZDOT_CELLS + 1
DEPTHS_M = [0.65, 0.75, 0.85, 0.95]  # cell centres: 0.6 + (i + 0.5) * 0.1
VELOCITIES_MPS = [-0.08, -0.04, 0.0, 0.04, 0.08]  # -0.1 + (i + 0.5) * 0.04
VALUES = np.linspace(-4.0, 0.5, STATES).astype("<f4")  # cell 19 (last depth row, fastest sinking) is the highest
ACTIONS = np.array([0, 1, 255, 0, 1] * Z_CELLS + [0], np.uint8)


def _traffic(act_bins: int = 1) -> list[Received]:
    """What a session hands its listeners when the agent runs one episode on that grid and dumps its tables."""
    states = Z_CELLS * ZDOT_CELLS * act_bins + 1
    values = VALUES if act_bins == 1 else np.linspace(-4.0, 0.5, states).astype("<f4")
    actions = ACTIONS if act_bins == 1 else np.zeros(states, np.uint8)
    frames: list[Received] = []

    def add(message: Message, t_s: float) -> None:
        seq = len(frames)
        inner = build_inner(0, seq, message.DEFINITION.msg_id, message.pack())
        frames.append(Received(Frame(0, seq, message.DEFINITION.msg_id, message, inner), START_NS + int(t_s * 1e9),
                               None, False))

    add(m.Hello(protocol_version=1, node_kind=1, definitions_hash=definitions_hash(), node_id=7, boot_id=11,
                name="grid"), 0.0)
    for index, (name, value) in enumerate((("z_cells", Z_CELLS), ("zdot_cells", ZDOT_CELLS), ("act_bins", act_bins))):
        add(m.ParamValue(index=index, count=3, param_type=ParamType.U8, value=value, minimum=1, maximum=50,
                         name=name), 0.0)
    add(m.EpisodeStart(t_us=0, episode=1, sample=0, start_state=7, depth_m=TARGET_M, velocity_mps=0.0,
                       target_depth_m=TARGET_M, z_tol_m=Z_TOL_M, zdot_tol_mps=ZDOT_TOL_MPS, p_explore=0.1), 0.0)
    for i in range(20):
        add(m.Sample(t_us=i * 100_000, sample=i, episode=1, step=i, pressure_pa=109_000.0, depth_m=TARGET_M,
                     velocity_mps=0.0, actuator_deg=65.0, actuator_cmd_deg=65.0, reward=0.0, state=7, action=i % 2,
                     mode=Mode.LEARNING), i / 10)
    add(m.EpisodeEnd(t_us=2_000_000, episode=1, sample=19, reason=EndReason.FAILURE, end_state=states - 1, steps=20,
                     duration_s=2.0, episode_return=-1.0, successes=0), 2.0)
    for dump_id, (kind, data) in enumerate(((DumpKind.VALUES, values.tobytes()), (DumpKind.POLICY, actions.tobytes()))):
        for offset in range(0, len(data), 224):  # a DUMP_CHUNK carries at most 247 payload bytes
            add(m.DumpChunk(dump_id=dump_id + 1, kind=kind, episode=1, total_bytes=len(data), offset=offset,
                            data=data[offset : offset + 224]), 2.0)
    return frames


@pytest.fixture(scope="module")
def recorded(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    """The view's .rrd of a live session on that grid, and the replay of the same session's MCAP recording."""
    directory = tmp_path_factory.mktemp("heatmap")
    with RerunView.open(ViewConfig(rrd=directory / "live.rrd")) as view:
        record(Traffic(_traffic(), []), directory / "session.mcap", [view])
    replay = ["replay", str(directory / "session.mcap"), "--rrd", str(directory / "replay.rrd")]
    result = CliRunner().invoke(app, replay)
    assert result.exit_code == 0, result.output
    return directory / "live.rrd", directory / "replay.rrd"


def _labels_at(texts: dict[str, list], axis: int, at: float) -> dict[float, str]:
    """Text labels whose position has coordinate `axis` equal to `at`, by their other coordinate."""
    return {pos[1 - axis]: label for pos, label in zip(texts["Points2D:positions"], texts["Points2D:labels"],
                                                        strict=True) if abs(pos[axis] - at) < 1e-6}


def _rgb(packed: int) -> tuple[int, int, int]:
    return (packed >> 24) & 0xFF, (packed >> 16) & 0xFF, (packed >> 8) & 0xFF


def _pixel(image: dict[str, list], cell: int) -> tuple[int, int, int]:
    buffer = image["Image:buffer"][0]
    return buffer[3 * cell], buffer[3 * cell + 1], buffer[3 * cell + 2]


@pytest.mark.parametrize("which", [0, 1], ids=["live", "replay"])
@pytest.mark.parametrize("heatmap", ["value_function", "policy"])
def test_the_axes_give_each_cell_its_depth_and_velocity(recorded: tuple[Path, Path], which: int, heatmap: str) -> None:
    texts = latest(recorded[which], f"/{heatmap}/frame/texts")
    assert "depth [m]" in texts["Points2D:labels"]
    assert any(label.startswith("velocity [m/s]") for label in texts["Points2D:labels"])
    # Velocity values under the grid's columns (x = column centre), depth values left of its rows (y = row centre).
    under = {x: float(text) for x, text in _labels_at(texts, 1, Z_CELLS + 0.9).items()}
    assert under == {i + 0.5: VELOCITIES_MPS[i] for i in (0, 2, 4)}  # both ends and zero; five would overlap
    left = {y: float(text) for y, text in _labels_at(texts, 0, -1.6).items() if y > 0}
    assert left == {i + 0.5: d for i, d in enumerate(DEPTHS_M)}
    image = latest(recorded[which], f"/{heatmap}/image")
    assert (image["Image:format"][0]["width"], image["Image:format"][0]["height"]) == (ZDOT_CELLS, Z_CELLS)


def test_the_policy_legend_says_which_colour_is_which_action(recorded: tuple[Path, Path]) -> None:
    live, _replay = recorded
    legend = latest(live, "/policy/frame/legend")
    meaning = dict(zip(legend["Points2D:labels"], map(_rgb, legend["Points2D:colors"]), strict=True))
    assert set(meaning) == {"sink", "rise", "untried"}
    image = latest(live, "/policy/image")
    # Cells 0, 1, 2 hold actions 0 (less volume: sink), 1 (more volume: rise) and 255 (never left the state).
    assert [_pixel(image, cell) for cell in (0, 1, 2)] == [meaning["sink"], meaning["rise"], meaning["untried"]]
    captions = latest(live, "/policy/frame/texts")["Points2D:labels"]
    assert {"action", "sink", "rise", "untried"} <= set(captions)  # drawn under the swatches: legend shows them


def test_the_value_legend_spans_the_dumped_values_with_the_image_colours(recorded: tuple[Path, Path]) -> None:
    live, _replay = recorded
    legend = latest(live, "/value_function/frame/legend")
    labels = legend["Points2D:labels"]
    assert labels[-1] == "untried"  # the cells the policy says were never left (issue 27)
    values = [float(text) for text in labels[:-1]]
    tried = ACTIONS[:-1] != 255
    grid_values = np.where(tried, VALUES[:-1], np.nan)  # the terminal state is not a cell; untried cells not scaled
    assert values[0] == pytest.approx(np.nanmax(grid_values), abs=1e-3)  # top swatch: the highest tried value
    assert values[-1] == pytest.approx(np.nanmin(grid_values), abs=1e-3)
    assert values == sorted(values, reverse=True)
    image = latest(live, "/value_function/image")
    colours = [_rgb(c) for c in legend["Points2D:colors"]]
    assert _pixel(image, int(np.nanargmax(grid_values))) == colours[0]
    assert _pixel(image, int(np.nanargmin(grid_values))) == colours[-2]
    assert _pixel(image, int(np.argmin(tried))) == colours[-1]  # an untried cell: the untried swatch's colour
    assert "v(s)" in latest(live, "/value_function/frame/texts")["Points2D:labels"]


def test_the_velocity_plot_and_the_heatmaps_are_scaled_for_the_agents_grid(recorded: tuple[Path, Path]) -> None:
    for rrd in recorded:
        ranges = blueprint_values(rrd, "ScalarAxis:range")
        assert ranges[0] == [[-0.12, 0.12]]  # the default bound 0.04 m/s, until the agent says otherwise
        assert ranges[-1] == [[pytest.approx(-3 * ZDOT_TOL_MPS), pytest.approx(3 * ZDOT_TOL_MPS)]]
        bounds = blueprint_values(rrd, "VisualBounds2D:range")[-1][0]
        assert bounds["x_range"][0] < -1.6 and bounds["x_range"][1] > ZDOT_CELLS + 1.5  # depth values, legend
        assert bounds["y_range"][0] < 0 and bounds["y_range"][1] > Z_CELLS + 2.0  # titles, velocity values


def test_with_actuator_bins_each_block_of_rows_gets_its_depth_values(tmp_path: Path) -> None:
    """The actuator3 learner's grid stacks one block of depth rows per actuator bin: each block is labelled."""
    with RerunView.open(ViewConfig(rrd=tmp_path / "live.rrd")) as view:
        for received in _traffic(act_bins=3):
            view.on_received(received)
    texts = latest(tmp_path / "live.rrd", "/value_function/frame/texts")
    left = {y: float(text) for y, text in _labels_at(texts, 0, -1.6).items() if y > 0}
    assert left == {block * Z_CELLS + i + 0.5: d for block in range(3) for i, d in enumerate(DEPTHS_M)}
    assert "depth [m] in actuator bins 1-3, top down" in texts["Points2D:labels"]
    image = latest(tmp_path / "live.rrd", "/value_function/image")
    assert (image["Image:format"][0]["width"], image["Image:format"][0]["height"]) == (ZDOT_CELLS, 3 * Z_CELLS)


def test_untried_cells_take_the_untried_colour_and_leave_the_scale() -> None:
    """A state the agent never left keeps its initial value (0, above every learned one, as rewards are <= 0): it is
    drawn in the policy's untried grey, and the colour scale is the tried cells' (issue 27 item 5)."""
    import numpy as np

    from groundstation.view.heatmap import UNTRIED, UNTRIED_ACTION, untried_cells, value_image, value_range

    values = np.array([-3.0, -1.0, 0.0, 0.0, -9.0], np.float32)  # 2 x 2 cells and the terminal state
    actions = np.array([0, 1, UNTRIED_ACTION, UNTRIED_ACTION, 0], np.uint8)
    untried = untried_cells(actions)
    assert value_range(values, 2, untried) == (-3.0, -1.0)
    image = value_image(values, 2, untried)
    assert image.shape == (2, 2, 3)
    assert tuple(image[1, 0]) == UNTRIED[0] and tuple(image[1, 1]) == UNTRIED[0]
    assert tuple(image[0, 1]) != UNTRIED[0] and tuple(image[0, 1]) != tuple(image[0, 0])  # best and worst differ
    assert value_range(values, 2) == (-3.0, 0.0)  # without a policy: every cell counts, as before
