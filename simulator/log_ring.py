"""The on-board log (SPEC.md s. 7): a ring of SAMPLE and EPISODE frames (inner bytes), keyed by sample index."""

from __future__ import annotations

from collections import deque
from itertools import islice
from typing import NamedTuple

LOG_CAPACITY_BYTES = 512 * 1024  # SPEC s. 7: two external M24M02 EEPROMs, 2 x 256 KiB = 524 288 B
RECORD_OVERHEAD_BYTES = 1  # the EEPROM record keeps a length byte before each inner frame


class LogRecord(NamedTuple):
    """One logged frame (a named tuple: one is built per control step, faster than a frozen dataclass)."""

    sample: int  # the frame's sample index (SAMPLE.sample, EPISODE_START/END.sample)
    inner: bytes  # the inner frame as produced (ver | flags | seq | msg_id | payload | crc)
    is_sample: bool = True  # a SAMPLE (else EPISODE_START / EPISODE_END)


class LogRing:
    """Records in production order; the oldest are overwritten once `capacity_bytes` is used.

    `first_sample` and `next_sample` are what HEARTBEAT and LOG_RANGE report: the oldest SAMPLE index
    still held and the index the next SAMPLE will get.
    """

    def __init__(self, capacity_bytes: int = LOG_CAPACITY_BYTES) -> None:
        if capacity_bytes <= 0:
            raise ValueError("capacity_bytes must be positive")
        self.capacity_bytes = capacity_bytes
        self._records: deque[LogRecord] = deque()
        self.bytes_used = 0
        self.next_sample = 0

    @property
    def first_sample(self) -> int:
        """The oldest sample index still held (equals next_sample when the log is empty)."""
        return self._records[0].sample if self._records else self.next_sample

    def __len__(self) -> int:
        return len(self._records)

    def append(self, sample: int, inner: bytes, is_sample: bool) -> None:
        """Store one frame; a SAMPLE moves next_sample past its index."""
        size = len(inner) + RECORD_OVERHEAD_BYTES
        if size > self.capacity_bytes:
            return
        records = self._records
        records.append(LogRecord(sample, inner, is_sample))
        self.bytes_used += size
        while self.bytes_used > self.capacity_bytes:
            self.bytes_used -= len(records.popleft().inner) + RECORD_OVERHEAD_BYTES
        if is_sample and sample >= self.next_sample:
            self.next_sample = sample + 1

    def records(self, first_sample: int, end_sample: int, max_samples: int = 0) -> list[LogRecord]:
        """Records whose sample index lies in [first_sample, end_sample), oldest first.

        With max_samples, the range is cut after the sample index of the max_samples-th SAMPLE record, so the
        EPISODE frames of that index come along (SPEC s. 7, LOG_REQUEST bound). A list, not a view: the caller
        re-sends it while the program keeps logging into the ring.
        """
        if not self._records or end_sample <= first_sample:
            return []
        out: list[LogRecord] = []
        samples, cut = 0, end_sample
        for record in islice(self._records, self._bisect(first_sample), None):
            if record.sample >= cut:
                break
            out.append(record)
            if max_samples and record.is_sample:
                samples += 1
                if samples == max_samples:
                    cut = min(cut, record.sample + 1)
        return out

    def _bisect(self, sample: int) -> int:
        """Index of the first record with sample index >= sample (indices never decrease)."""
        records = self._records
        low, high = 0, len(records)
        while low < high:
            mid = (low + high) // 2
            if records[mid].sample < sample:
                low = mid + 1
            else:
                high = mid
        return low

