"""`dive dump --png`: the value function or the policy as a picture, in the live view's colours and grid.

One panel per actuator bin; depth down the side (shallow on top, as under water, the target depth dashed), velocity
across (rising on the left). The value panel has a colour bar; the policy panel a legend of the actions and of the
states never left.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from groundstation.view.heatmap import (
    POLICY_COLOURS,
    UNTRIED,
    Grid,
    policy_image,
    value_image,
    value_palette,
    value_range,
)
from protocol import DumpKind

if TYPE_CHECKING:
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

PANEL_INCHES = 3.6


def write_dump_png(path: Path, kind: DumpKind, values: NDArray[np.generic], grid: Grid, episode: int) -> None:
    """Draw a VALUES (float32 per state) or POLICY (uint8 per state) dump over `grid` into the PNG `path`."""
    # Imported here: matplotlib costs ~0.3 s, and only --png needs it. The object API, not pyplot: no global state.
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure
    from matplotlib.ticker import MaxNLocator

    value_span: tuple[float, float] | None = None  # the colour bar's, for VALUES
    if kind == DumpKind.VALUES:
        floats = values.astype(np.float32)
        image = value_image(floats, grid.zdot_cells)
        value_span = value_range(floats, grid.zdot_cells)
        what = f"value function v(s); outside the region {float(values[-1]):.3g}"
    else:
        image = policy_image(values.astype(np.uint8), grid.zdot_cells)
        what = "greedy policy"
    figure = Figure(figsize=(PANEL_INCHES * grid.blocks + 1.4, PANEL_INCHES + 0.6), layout="constrained")
    FigureCanvasAgg(figure)
    axes = figure.subplots(1, grid.blocks, squeeze=False)[0]
    shallow_m, deep_m = grid.target_depth_m - grid.z_tol_m, grid.target_depth_m + grid.z_tol_m
    for block, ax in enumerate(axes):
        rows = image[block * grid.z_cells : (block + 1) * grid.z_cells]
        ax.imshow(rows, extent=(-grid.zdot_tol_mps, grid.zdot_tol_mps, deep_m, shallow_m), aspect="auto",
                  interpolation="nearest")
        ax.xaxis.set_major_locator(MaxNLocator(4))  # five labels of "-0.03" overlap in a panel this wide
        ax.axhline(grid.target_depth_m, color="white", linewidth=0.8, linestyle="--")
        ax.set_xlabel("velocity ż [m/s] (rising left)")
        if block == 0:
            ax.set_ylabel("depth z [m]")
        if grid.blocks > 1:
            ax.set_title(f"actuator bin {block}")
    if value_span is not None:
        _value_bar(figure, axes, *value_span)
    else:
        _policy_legend(figure)
    figure.suptitle(f"{what}, episode {episode}")
    figure.savefig(path, format="png", dpi=100)


def _value_bar(figure: Figure, axes: Sequence[Axes], low: float, high: float) -> None:
    from matplotlib.cm import ScalarMappable
    from matplotlib.colors import ListedColormap, Normalize

    mappable = ScalarMappable(Normalize(low, high if high > low else low + 1.0), ListedColormap(value_palette()))
    figure.colorbar(mappable, ax=list(axes), label="v(s)")


def _policy_legend(figure: Figure) -> None:
    from matplotlib.patches import Patch

    entries = [*POLICY_COLOURS.values(), UNTRIED]
    handles = [Patch(color=(r / 255, g / 255, b / 255), label=meaning) for (r, g, b), meaning in entries]
    figure.legend(handles=handles, loc="outside right center")
