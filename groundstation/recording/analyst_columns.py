"""The columns an analyst would otherwise join by hand (issue 40): added to the Parquet tables at export.

- `agent_t_us` on every row the ground made (markers, events, link statistics, commands sent): the agent's clock at
  that host time, from a straight line fitted per boot to the live SAMPLEs' (host time, agent time) pairs, so a
  marker and the samples around it compare on one clock with a WHERE (PlotJuggler's and Foxglove's way: one time);
- `mode_name` and `action_name` beside `mode` and `action`: the enums' names, dictionary-encoded;
- `target_depth_m` on samples: the target of the episode a sample belongs to (EPISODE_START's, as of its sample
  index), before the first episode the recording's parameter, so "distance from the target" needs no join;
- float32 fields (the wire's F32) stored as float32: 0.4, not 0.4000000059604645, in every tool that prints them.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from protocol import Action, Mode, UnknownMessageError
from protocol.fields import F32_WIRE
from protocol.registry import message_class_by_name

_MODE_NAMES = {int(mode): mode.name for mode in Mode}
_ACTION_NAMES = {int(action): action.name.lower() for action in Action}
LABELLED = {"mode": ("mode_name", _MODE_NAMES), "action": ("action_name", _ACTION_NAMES)}


def float32_fields(topic: str) -> frozenset[str]:
    """The F32 fields of an agent or ground message's topic (/agent/SAMPLE: depth_m, ...); none for other topics."""
    prefix, _, name = topic.rpartition("/")
    if prefix not in ("/agent", "/ground"):
        return frozenset()
    try:
        message = message_class_by_name(name)
    except UnknownMessageError:
        return frozenset()
    return frozenset(f.name for f in message.DEFINITION.fields if f.wire == F32_WIRE)


def label(values: NDArray[Any], names: dict[int, str]) -> list[str | None]:
    """Each integer's name (None for a value the enum does not know: it is data, not ours to invent)."""
    return [names.get(int(v)) for v in values]


class AgentClock:
    """Host time -> agent time per boot: t_us = slope * host_ns + intercept, fitted to the live SAMPLEs.

    Backfilled samples are left out (they arrived long after the agent sent them). A least-squares line, not
    TIMESYNC's offset: it holds for a simulator run at --speed 50 as for a real agent, and batches that share one
    arrival time average out.
    """

    def __init__(self, samples: NDArray[np.void]) -> None:
        self._lines: dict[int, tuple[float, float]] = {}
        names = samples.dtype.names or ()
        if not len(samples) or not {"boot", "host_time_ns", "t_us"} <= set(names):
            return
        live = ~samples["_backfilled"].astype(bool) if "_backfilled" in names else np.ones(len(samples), bool)
        for boot in np.unique(samples["boot"]):
            chosen = live & (samples["boot"] == boot)
            host, agent = samples["host_time_ns"][chosen].astype(np.float64), samples["t_us"][chosen].astype(np.float64)
            if len(host) < 2 or np.ptp(host) == 0:
                continue
            host0 = host.mean()
            slope, intercept = np.polyfit(host - host0, agent, 1)
            self._lines[int(boot)] = (float(slope), float(intercept - slope * host0))

    def agent_us(self, boots: NDArray[Any], host_ns: NDArray[Any]) -> list[int | None]:
        """The agent time of each (boot, host time); None where the boot had too few live samples to tell."""
        out: list[int | None] = []
        for boot, host in zip(boots.tolist(), host_ns.tolist(), strict=True):
            line = self._lines.get(int(boot))
            out.append(None if line is None else int(round(line[0] * host + line[1])))
        return out


def sample_targets(samples: NDArray[np.void], starts: NDArray[np.void], default_m: float | None) -> NDArray[Any]:
    """The target depth of each sample: its boot's latest EPISODE_START at or before its index; `default_m` (the
    recording's target_depth_m parameter) before the first, NaN when there is none."""
    out = np.full(len(samples), np.nan if default_m is None else default_m, dtype=np.float32)
    names = starts.dtype.names or ()
    if not len(samples) or not len(starts) or not {"boot", "sample", "target_depth_m"} <= set(names):
        return out
    for boot in np.unique(samples["boot"]):
        in_boot = starts[starts["boot"] == boot]
        if not len(in_boot):
            continue
        in_boot = in_boot[np.argsort(in_boot["sample"], kind="stable")]
        rows = np.flatnonzero(samples["boot"] == boot)
        at = np.searchsorted(in_boot["sample"], samples["sample"][rows], side="right") - 1
        known = at >= 0
        out[rows[known]] = in_boot["target_depth_m"][at[known]]
    return out
