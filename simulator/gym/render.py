"""The `rgb_array` picture of DivingAgent-v0: depth against its target and bounds, and the actuator."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

_SIZE_IN = (6.4, 4.0)
_DPI = 80


def episode_image(
    trace: list[tuple[float, float, float]], target_m: float, z_tol_m: float, window_deg: float
) -> NDArray[np.uint8]:
    """An (H, W, 3) uint8 image of one episode's trace of (time s, depth m, actuator offset deg)."""
    # Imported here: matplotlib costs ~0.3 s, and only rendering needs it.
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    times, depths, offsets = (np.array(column) for column in zip(*trace, strict=True))
    figure = Figure(figsize=_SIZE_IN, dpi=_DPI)
    canvas = FigureCanvasAgg(figure)
    depth_ax, act_ax = figure.subplots(2, 1, sharex=True)
    depth_ax.plot(times, depths, color="tab:blue", label="depth")
    depth_ax.axhline(target_m, color="tab:green", label="target")
    for bound in (target_m - z_tol_m, target_m + z_tol_m):
        depth_ax.axhline(bound, color="tab:red", linestyle="--")
    depth_ax.invert_yaxis()  # z is positive down: deeper is lower on the picture
    depth_ax.set_ylabel("depth [m]")
    depth_ax.legend(loc="upper right", fontsize="small")
    act_ax.plot(times, offsets, color="tab:orange")
    act_ax.set_ylim(-1.1 * window_deg, 1.1 * window_deg)
    act_ax.set_ylabel("actuator [deg]")
    act_ax.set_xlabel("time in episode [s]")
    figure.tight_layout()
    canvas.draw()
    return np.asarray(canvas.buffer_rgba())[:, :, :3].copy()
