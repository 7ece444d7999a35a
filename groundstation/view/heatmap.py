"""The value-function and policy heatmaps: colours per grid cell, and the axes and legend drawn around them."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from protocol import Action
from protocol.parameters import param

Colour = tuple[int, int, int]
AXIS_COLOUR: Colour = (150, 150, 150)
POLICY_COLOURS: dict[int, tuple[Colour, str]] = {  # the POLICY dump's actions (SPEC.md section 10)
    0: ((230, 120, 30), "sink"),  # less volume
    1: ((40, 120, 220), "rise"),  # more volume
}
UNTRIED: tuple[Colour, str] = ((90, 90, 90), "untried")
UNTRIED_ACTION = int(Action.NONE)  # a POLICY dump's action for a state the agent never left (SPEC.md section 10)
_MAX_TICKS = 4  # labels per axis: more overlap in a panel a third of the screen wide
_LEGEND_STEPS = 5  # colour swatches of the value legend, from the highest value down to the lowest
SWATCH_RADIUS = 0.4  # a legend swatch's radius in cells
_TOP_TITLE_Y = -2.2  # a title above the "outside" state's box (at y = -1)

# Shown when the grid's geometry is not yet known: the agent's defaults (SPEC.md section 13).
DEFAULT_GRID = {name: param(name).default for name in ("target_depth_m", "z_tol_m", "zdot_tol_mps", "z_cells",
                                                        "zdot_cells", "act_bins")}


@dataclass(frozen=True, slots=True)
class Grid:
    """The learner's (depth, velocity) grid, as the heatmap draws it: one pixel per cell.

    Rows are depth cells, shallow on top (z is positive down, as the 2D view's y); columns are velocity cells,
    rising on the left. With several actuator bins the image stacks one block of z_cells rows per bin.
    """

    target_depth_m: float
    z_tol_m: float
    zdot_tol_mps: float
    z_cells: int
    zdot_cells: int
    blocks: int = 1

    @property
    def rows(self) -> int:
        return self.z_cells * self.blocks

    def depth_centres_m(self) -> NDArray[np.float64]:
        """Depth at each depth cell's centre (the learner's cell i spans target - z_tol + [i, i+1] * width)."""
        width_m = 2.0 * self.z_tol_m / self.z_cells
        return self.target_depth_m - self.z_tol_m + (np.arange(self.z_cells, dtype=np.float64) + 0.5) * width_m

    def velocity_centres_mps(self) -> NDArray[np.float64]:
        width_mps = 2.0 * self.zdot_tol_mps / self.zdot_cells
        return -self.zdot_tol_mps + (np.arange(self.zdot_cells, dtype=np.float64) + 0.5) * width_mps


def default_grid() -> Grid:
    g = DEFAULT_GRID
    return Grid(g["target_depth_m"], g["z_tol_m"], g["zdot_tol_mps"], int(g["z_cells"]), int(g["zdot_cells"]),
                int(g["act_bins"]))


def dump_grid(states: int, target_depth_m: float, z_tol_m: float, zdot_tol_mps: float, z_cells: int,
              zdot_cells: int) -> Grid | None:
    """The grid a dump of `states` states covers (its terminal state last); None when it holds not one row of cells.

    A dump whose rows are not whole blocks of z_cells (parameters not seen, or another grid than they say) is drawn
    as one block of its own rows.
    """
    rows = (states - 1) // zdot_cells
    if rows < 1:
        return None
    if rows % z_cells:
        z_cells = rows
    return Grid(target_depth_m, z_tol_m, zdot_tol_mps, z_cells, zdot_cells, rows // z_cells)


def value_palette(steps: int = 256) -> NDArray[np.float64]:
    """The value heatmap's colours from lowest to highest, as RGB in 0..1 (a plot's colour bar)."""
    return _colormap(np.linspace(0.0, 1.0, steps)) / 255.0


@dataclass(frozen=True, slots=True)
class Label:
    """A text at a point of the heatmap's plane (cell units: the image's pixels), with a swatch colour."""

    x: float
    y: float
    text: str
    colour: Colour = AXIS_COLOUR


@dataclass(frozen=True, slots=True)
class Bounds:
    """A rectangle of the heatmap's plane, in cells."""

    x_min: float
    x_max: float
    y_min: float
    y_max: float


def bounds(grid: Grid) -> Bounds:
    """The grid and what is drawn around it: depth values left, legend right, velocity values and title below,
    titles and the box of the "outside" state above.

    Rerun draws a label centred under its point at a fixed size on screen; these margins hold labels of up to
    about 60 pixels at the ~25 pixels per cell a heatmap panel of the shipped layout gives a 10 x 10 grid.
    """
    return Bounds(-3.0, grid.zdot_cells + 3.2, -1.6 if grid.blocks == 1 else _TOP_TITLE_Y - 0.2, grid.rows + 2.9)


@dataclass(frozen=True, slots=True)
class Frame:
    """What is drawn around a heatmap: axis lines and tick marks, texts (tick values, titles, legend captions),
    and the legend's colour swatches (each labelled with what its colour means, as its caption says)."""

    lines: tuple[tuple[tuple[float, float], ...], ...]
    texts: tuple[Label, ...]
    swatches: tuple[Label, ...]
    bounds: Bounds  # what the view must show to hold all of it


def _colormap(unit: NDArray[np.float64]) -> NDArray[np.uint8]:
    """Viridis-like colours for values in 0..1 (five anchors, linear in between)."""
    anchors = np.array([[68, 1, 84], [59, 82, 139], [33, 145, 140], [94, 201, 98], [253, 231, 37]], float)
    pos = np.clip(unit, 0.0, 1.0) * (len(anchors) - 1)
    low = np.minimum(pos.astype(int), len(anchors) - 2)
    frac = (pos - low)[..., None]
    return (anchors[low] * (1 - frac) + anchors[low + 1] * frac).astype(np.uint8)


def _grid_cells(values: NDArray[np.generic], zdot_cells: int) -> NDArray[np.generic]:
    """The grid's states: the dump less its terminal state, cut to whole rows."""
    return values[: (len(values) - 1) // zdot_cells * zdot_cells]


def untried_cells(actions: NDArray[np.uint8]) -> NDArray[np.bool_]:
    """The states a POLICY dump marks untried (the agent never left them): their value is the initial one."""
    return np.asarray(actions) == UNTRIED_ACTION


def _tried(values: NDArray[np.float32], zdot_cells: int, untried: NDArray[np.bool_] | None) -> NDArray[np.bool_]:
    cells = len(_grid_cells(values, zdot_cells))
    if untried is None or len(untried) != len(values):
        return np.ones(cells, bool)
    return ~untried[:cells]


def value_range(values: NDArray[np.float32], zdot_cells: int,
                untried: NDArray[np.bool_] | None = None) -> tuple[float, float]:
    """The lowest and highest value of the tried cells (an untried cell's initial value would set the scale)."""
    cells = _grid_cells(values, zdot_cells).astype(np.float64)[_tried(values, zdot_cells, untried)]
    return (float(np.min(cells)), float(np.max(cells))) if len(cells) else (0.0, 0.0)


def value_image(values: NDArray[np.float32], zdot_cells: int,
                untried: NDArray[np.bool_] | None = None) -> NDArray[np.uint8]:
    """v(s) over the grid, coloured from its lowest (dark) to its highest value (yellow); `untried` cells (from the
    latest POLICY dump) in the policy's untried grey, not in the colour of the best value they start with."""
    cells = _grid_cells(values, zdot_cells).astype(np.float64)
    low, high = value_range(values, zdot_cells, untried)
    unit = (cells - low) / (high - low) if high > low else np.zeros_like(cells)
    image = _colormap(unit)
    image[~_tried(values, zdot_cells, untried)] = UNTRIED[0]
    return image.reshape(-1, zdot_cells, 3)


def policy_image(actions: NDArray[np.uint8], zdot_cells: int) -> NDArray[np.uint8]:
    """The greedy action per cell: POLICY_COLOURS, grey where the agent never left the state."""
    cells = _grid_cells(actions, zdot_cells)
    image = np.empty((len(cells), 3), np.uint8)
    image[:] = UNTRIED[0]
    for action, (colour, _meaning) in POLICY_COLOURS.items():
        image[cells == action] = colour
    return image.reshape(-1, zdot_cells, 3)


def _tick_cells(cells: int) -> list[int]:
    """At most _MAX_TICKS cells, the first and the last among them, evenly spaced where the count allows
    (10 cells: 0, 3, 6, 9; 5 cells: 0, 2, 4, the middle one at zero velocity), else as nearly as it does."""
    last = cells - 1
    for step in range(1, last + 1):
        if last % step == 0 and last // step + 1 <= _MAX_TICKS:
            if last // step + 1 >= min(3, cells):
                return list(range(0, cells, step))
            break
    return sorted({round(i) for i in np.linspace(0, last, min(cells, _MAX_TICKS))})


def _number(value: float) -> str:
    text = f"{value:.3g}"
    return "0" if text == "-0" else text


def axes(grid: Grid) -> tuple[tuple[tuple[tuple[float, float], ...], ...], tuple[Label, ...]]:
    """Axis lines along the left and bottom edges, tick marks and values at cell centres, the axis titles."""
    width, rows = float(grid.zdot_cells), float(grid.rows)
    mark = 0.25  # tick mark length in cells
    lines: list[tuple[tuple[float, float], ...]] = [((0.0, 0.0), (0.0, rows), (width, rows))]
    labels: list[Label] = []
    velocities = grid.velocity_centres_mps()
    for i in _tick_cells(grid.zdot_cells):
        x = i + 0.5
        lines.append(((x, rows), (x, rows + mark)))
        labels.append(Label(x, rows + 0.9, _number(velocities[i])))
    labels.append(Label(width / 2, rows + 2.0, "velocity [m/s] (rising <- -> sinking)"))
    depths = grid.depth_centres_m()
    for block in range(grid.blocks):
        top = block * grid.z_cells
        for i in _tick_cells(grid.z_cells):
            y = top + i + 0.5
            lines.append(((0.0, y), (-mark, y)))
            labels.append(Label(-1.6, y, _number(depths[i])))
        if block:
            lines.append(((0.0, float(top)), (width, float(top))))  # where the next actuator bin's block starts
    if grid.blocks == 1:
        labels.append(Label(-1.6, -1.0, "depth [m]"))
    else:  # one title above the "outside" box, not a label per block (it would sit on the depth values)
        labels.append(Label(width / 2, _TOP_TITLE_Y, f"depth [m] in actuator bins 1-{grid.blocks}, top down"))
    return tuple(lines), tuple(labels)


def _legend(grid: Grid, title: str, swatches: list[tuple[Colour, str]]) -> tuple[tuple[Label, ...], tuple[Label, ...]]:
    """Swatches in a column right of the grid, top to bottom, each captioned just below its dot."""
    x = grid.zdot_cells + 1.5
    ys = np.linspace(0.5, max(grid.rows, 2.5 * len(swatches)) - 0.5, len(swatches))
    dots = tuple(Label(x, float(y), meaning, colour) for (colour, meaning), y in zip(swatches, ys, strict=True))
    captions = tuple(Label(x, dot.y + SWATCH_RADIUS, dot.text) for dot in dots)
    return (Label(x, -1.0, title), *captions), dots


def value_frame(grid: Grid, low: float, high: float) -> Frame:
    """The value function's frame: its legend has _LEGEND_STEPS swatches from `high` (top) down to `low`."""
    lines, texts = axes(grid)
    units = np.linspace(1.0, 0.0, _LEGEND_STEPS)
    swatches = [((int(c[0]), int(c[1]), int(c[2])), _number(low + (high - low) * unit))
                for unit, c in zip(units, _colormap(units), strict=True)]
    captions, dots = _legend(grid, "v(s)", [*swatches, UNTRIED])
    return Frame(lines, texts + captions, dots, bounds(grid))


def policy_frame(grid: Grid) -> Frame:
    lines, texts = axes(grid)
    captions, dots = _legend(grid, "action", [*POLICY_COLOURS.values(), UNTRIED])
    return Frame(lines, texts + captions, dots, bounds(grid))
