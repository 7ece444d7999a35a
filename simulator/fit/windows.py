"""Cut the recorded samples into windows the plant model can be run over: contiguous, submerged, one mode."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from protocol import Mode
from simulator.fit.reader import FitError, Samples

# Modes in which the hull moves freely under the gear's command (IDLE rests at the surface).
_FREE = np.array([Mode.LEARNING, Mode.RECOVERING, Mode.HOVER, Mode.SURFACING, Mode.PAUSED])
MIN_DEPTH_M = 0.05  # shallower, the hull may break the surface: another physics than the model's
MAX_GAP_S = 0.5  # a longer gap between samples is a pause of the link or the agent, not one held command
MIN_WINDOW_SAMPLES = 20


@dataclass
class Windows:
    """Samples in windows; window w is [starts[w], ends[w]) of the arrays, the command held between samples."""

    t_s: NDArray[np.float64]
    depth_m: NDArray[np.float64]
    alpha_deg: NDArray[np.float64]
    cmd_deg: NDArray[np.float64]
    starts: NDArray[np.int64]
    ends: NDArray[np.int64]
    # The recorded (motor-side) angle of every sample in order, where the gear train's history restarts (a boot,
    # a re-placed agent), and the sample each window starts at: the output angle behind the backlash at a
    # window's start is that history run through the gear's play (kernel.gear_outputs). Empty: each window
    # starts with its gear train closed.
    history_deg: NDArray[np.float64] = field(default_factory=lambda: np.zeros(0))
    history_reset: NDArray[np.bool_] = field(default_factory=lambda: np.zeros(0, dtype=np.bool_))
    start_rows: NDArray[np.int64] = field(default_factory=lambda: np.zeros(0, dtype=np.int64))

    @property
    def count(self) -> int:
        return len(self.starts)

    @property
    def seconds(self) -> float:
        """Agent time covered by the windows."""
        return float(np.sum(self.t_s[self.ends - 1] - self.t_s[self.starts]))

    def owner(self) -> NDArray[np.int64]:
        """The window each sample belongs to."""
        return np.repeat(np.arange(self.count), self.ends - self.starts)


def cut_windows(samples: Samples, window_s: float, max_depth_m: float) -> Windows:
    """Windows of at most window_s seconds over the usable, unbroken stretches of the samples.

    Deeper than max_depth_m the pressure sensor is at the end of its range (it reads a constant, not the depth).
    """
    usable = np.isin(samples.mode, _FREE) & (samples.depth_m > MIN_DEPTH_M) & (samples.depth_m < max_depth_m)
    dt = np.diff(samples.t_s)
    # Between sample i and i+1 the command recorded with i was held, unless one of these breaks the chain:
    # a missing sample, another run, a long gap, a new episode (the paper preset re-places the agent) or a
    # mode change (the new mode may set its command after the sample was sent).
    joined = (
        usable[:-1] & usable[1:]
        & (np.diff(samples.index) == 1) & (np.diff(samples.run) == 0)
        & (dt > 0) & (dt <= MAX_GAP_S)
        & ~samples.episode_start[1:] & (np.diff(samples.mode) == 0)
    )
    pieces: list[NDArray[np.int64]] = []
    # Stretches: maximal runs of joined pairs, as sample index ranges [first, last].
    edges = np.flatnonzero(np.diff(np.concatenate(([0], joined.astype(np.int8), [0]))))
    for first, stop in zip(edges[::2], edges[1::2], strict=True):
        span = np.arange(first, stop + 1)  # pairs first..stop-1 join samples first..stop
        duration = samples.t_s[span[-1]] - samples.t_s[span[0]]
        parts = max(1, int(np.ceil(duration / window_s - 1e-9)))
        for part in np.array_split(span, parts):
            if len(part) >= MIN_WINDOW_SAMPLES:
                pieces.append(part)
    if not pieces:
        raise FitError(
            f"no stretch of {MIN_WINDOW_SAMPLES} unbroken samples between {MIN_DEPTH_M} and {max_depth_m:.2f} m in "
            f"{', '.join(str(f) for f in samples.files)}: nothing to fit (record the agent diving)"
        )
    rows = np.concatenate(pieces)
    lengths = np.array([len(p) for p in pieces], dtype=np.int64)
    ends = np.cumsum(lengths)
    reset = np.ones(len(samples.t_s), dtype=np.bool_)
    reset[1:] = (np.diff(samples.run) != 0) | samples.episode_start[1:]
    return Windows(
        t_s=samples.t_s[rows], depth_m=samples.depth_m[rows], alpha_deg=samples.alpha_deg[rows],
        cmd_deg=samples.cmd_deg[rows], starts=ends - lengths, ends=ends,
        history_deg=samples.alpha_deg.astype(np.float64), history_reset=reset,
        start_rows=np.array([p[0] for p in pieces], dtype=np.int64),
    )
