"""Link statistics: frames and bytes each way, loss from sequence numbers, rejects by cause, RTT percentiles."""

from __future__ import annotations

import bisect
import statistics
import threading
from collections import deque
from typing import Any

from protocol import DecoderStats


def percentile(values: list[float], fraction: float) -> float:
    """Nearest-rank percentile of a non-empty list."""
    ordered = sorted(values)
    index = min(len(ordered) - 1, max(0, round(fraction * (len(ordered) - 1))))
    return ordered[index]


class LinkStats:
    """Counters the session updates; snapshot() is what /link records and the progress line shows."""

    def __init__(self, rtt_window: int = 200) -> None:
        self._lock = threading.Lock()
        self.tx_frames = 0
        self.tx_bytes = 0
        self.retries = 0
        self.command_timeouts = 0
        self.backfilled = 0
        self.reconnects = 0
        self.timesyncs_ignored = 0  # TIMESYNC answers that were no measurement (SessionCore: range-checked)
        self._rtts_s: deque[float] = deque(maxlen=rtt_window)
        # The same window kept sorted: every command's ACK timeout needs the median, and sorting 200 values
        # on the send path cost more than the rest of sending a command.
        self._rtts_sorted: list[float] = []

    def sent(self, nbytes: int, retry: bool = False) -> None:
        with self._lock:
            self.tx_frames += 1
            self.tx_bytes += nbytes
            self.retries += int(retry)

    def round_trip(self, seconds: float) -> None:
        with self._lock:
            window = self._rtts_s
            ordered = self._rtts_sorted
            if len(window) == window.maxlen:
                del ordered[bisect.bisect_left(ordered, window[0])]  # the one the append below drops
            window.append(seconds)
            bisect.insort(ordered, seconds)

    def rtt_median_s(self) -> float | None:
        """statistics.median of the window, read from the sorted copy."""
        with self._lock:
            ordered = self._rtts_sorted
            n = len(ordered)
            if not n:
                return None
            middle = n // 2
            return ordered[middle] if n % 2 else (ordered[middle - 1] + ordered[middle]) / 2

    def snapshot(self, rx: DecoderStats) -> dict[str, Any]:
        with self._lock:
            rtts = list(self._rtts_s)
            out: dict[str, Any] = {
                "rx_frames": rx.frames,
                "rx_bytes": rx.bytes,
                "rx_lost": rx.lost,
                "rx_duplicates": rx.duplicates,
                "rx_rejects": rx.rejects,
                "rejects": {
                    "cobs": rx.cobs_errors, "runt": rx.runts, "crc": rx.crc_errors,
                    "incompatible": rx.incompatible, "unknown_id": rx.unknown_id, "oversize": rx.oversize,
                    "malformed": rx.malformed,
                },
                "tx_frames": self.tx_frames,
                "tx_bytes": self.tx_bytes,
                "retries": self.retries,
                "command_timeouts": self.command_timeouts,
                "backfilled": self.backfilled,
                "reconnects": self.reconnects,
                "timesyncs_ignored": self.timesyncs_ignored,
                "rtt_median_ms": statistics.median(rtts) * 1e3 if rtts else None,
                "rtt_p95_ms": percentile(rtts, 0.95) * 1e3 if rtts else None,
            }
        total = rx.frames + rx.lost
        out["loss_fraction"] = rx.lost / total if total else 0.0
        return out
