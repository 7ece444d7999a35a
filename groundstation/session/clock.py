"""Clock model from TIMESYNC round trips (SPEC.md section 9): agent time -> host time, with drift."""

from __future__ import annotations

import statistics
from collections import deque
from dataclasses import dataclass

U64_MAX = 2**64 - 1
MAX_ROUND_TRIP_US = 30_000_000  # an answer later than this is no measurement of the clocks (SPEC.md section 9)
MAX_AGENT_HOLD_US = 10_000_000  # the agent's receive -> transmit: it answers at once, never seconds later
HOST_NS_LIMIT = 2**63  # a host time at or past this (year 2262) or below 0 is not a time: no MCAP can hold it


def host_ns_or_none(host_ns: int | float | None) -> int | None:
    """`host_ns` if it is a time a recording can hold (0 <= t < 2^63 ns), else None."""
    if host_ns is None or not 0 <= host_ns < HOST_NS_LIMIT:
        return None
    return int(host_ns)


def timesync_problem(t1_us: int, t2_us: int, t3_us: int, t4_us: int) -> str | None:
    """Why a TIMESYNC answer (origin, agent receive, agent transmit, host receive) is no measurement, or None.

    Every number in it came over the link: one agent (or one frame changed on the way) saying 2^64-1 would
    otherwise move the clock model by centuries and every recorded time with it.
    """
    if not t1_us <= t4_us or t4_us - t1_us > MAX_ROUND_TRIP_US:
        return f"origin {t1_us} is not a request sent in the last {MAX_ROUND_TRIP_US // 1_000_000} s"
    if not 0 < t2_us <= t3_us < U64_MAX or t3_us - t2_us > MAX_AGENT_HOLD_US:
        return f"agent times {t2_us} -> {t3_us} are not a receive and a transmit"
    return None


@dataclass(frozen=True, slots=True)
class SyncSample:
    host_us: float  # host time at the middle of the exchange
    offset_us: float  # agent clock - host clock
    round_trip_us: float


class ClockModel:
    """offset(t) = offset_us + drift * (t - ref_us), fitted over the exchanges with the smallest round trips.

    A round trip bounds the error of its offset by half its length, so the fastest exchanges are the
    trustworthy ones; a least-squares line through them gives the drift (rate difference of the clocks).
    """

    def __init__(self, window: int = 32, best: int = 8) -> None:
        self._samples: deque[SyncSample] = deque(maxlen=window)
        self._best = best
        self.offset_us: float | None = None
        self.drift: float = 0.0  # d(offset)/d(host time), dimensionless (1e-6 = 1 ppm)
        self.ref_us: float = 0.0

    @property
    def synced(self) -> bool:
        return self.offset_us is not None

    def reset(self) -> None:
        """The agent rebooted: its clock restarted."""
        self._samples.clear()
        self.offset_us = None
        self.drift = 0.0

    def add(self, t1_us: int, t2_us: int, t3_us: int, t4_us: int) -> SyncSample:
        round_trip = (t4_us - t1_us) - (t3_us - t2_us)
        offset = ((t2_us - t1_us) + (t3_us - t4_us)) / 2
        sample = SyncSample((t1_us + t4_us) / 2, offset, float(round_trip))
        self._samples.append(sample)
        self._fit()
        return sample

    def _fit(self) -> None:
        chosen = sorted(self._samples, key=lambda s: s.round_trip_us)[: self._best]
        chosen.sort(key=lambda s: s.host_us)
        self.ref_us = chosen[-1].host_us
        if len(chosen) >= 3 and chosen[-1].host_us - chosen[0].host_us > 0:
            xs = [s.host_us - self.ref_us for s in chosen]
            ys = [s.offset_us for s in chosen]
            slope, intercept = statistics.linear_regression(xs, ys)
            self.drift, self.offset_us = slope, intercept
        else:
            self.drift, self.offset_us = 0.0, chosen[-1].offset_us

    def offset_at(self, host_us: float) -> float | None:
        if self.offset_us is None:
            return None
        return self.offset_us + self.drift * (host_us - self.ref_us)

    def to_host_ns(self, agent_us: int) -> int | None:
        """Host time (ns since the epoch) of an agent clock reading, or None before the first sync."""
        if self.offset_us is None or self.drift <= -1.0:
            return None
        # agent = host + offset0 + drift*(host - ref)  =>  host = (agent - offset0 + drift*ref) / (1 + drift)
        host_us = (agent_us - self.offset_us + self.drift * self.ref_us) / (1.0 + self.drift)
        return host_ns_or_none(host_us * 1000)  # an agent time of 2^64-1 maps to no time a recording holds

    def as_dict(self) -> dict[str, float | None]:
        rtts = [s.round_trip_us for s in self._samples]
        return {
            "offset_us": self.offset_us,
            "drift_ppm": self.drift * 1e6,
            "round_trip_min_us": min(rtts) if rtts else None,
            "exchanges": float(len(rtts)),
        }
