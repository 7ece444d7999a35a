"""The on-board log (SPEC.md s. 7): a ring of SAMPLE and EPISODE frames (inner bytes), keyed by sample index.

The records live in numpy arrays, not Python objects, so that a compiled batch of control steps
(onboard_batch.py) appends its SAMPLEs where they lie: `ring_append` is the one way in, from Python
(`LogRing.append`) and from compiled code alike.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import njit
from numpy.typing import NDArray

from learning.spec import direct_entry

LOG_CAPACITY_BYTES = 512 * 1024  # SPEC s. 7: two external M24M02 EEPROMs, 2 x 256 KiB = 524 288 B
RECORD_OVERHEAD_BYTES = 1  # the EEPROM record keeps a length byte before each inner frame
_MIN_RECORD_BYTES = 8  # the shortest inner frame (7 bytes, an empty payload) and its length byte
_LONGEST_INNER = 255  # a record's length byte bounds the inner frames the log can hold
_ROWS_PER_READ = 1024

# The ring's counters (one int64 array, shared with compiled code). Records [HEAD, TAIL) of the index are
# held; their bytes lie in the data arena from the HEAD record's offset to DATA_END.
HEAD, TAIL, DATA_END, BYTES_USED, NEXT_SAMPLE, CAPACITY = 0, 1, 2, 3, 4, 5
N_COUNTERS = 6
# Columns of the record index.
R_SAMPLE, R_OFFSET, R_LENGTH, R_IS_SAMPLE = 0, 1, 2, 3


class LogRecord(NamedTuple):
    """One logged frame, as LOG_REQUEST replays it."""

    sample: int  # the frame's sample index (SAMPLE.sample, EPISODE_START/END.sample)
    inner: bytes  # the inner frame as produced (ver | flags | seq | msg_id | payload | crc)
    is_sample: bool = True  # a SAMPLE (else EPISODE_START / EPISODE_END)


@njit(cache=True, error_model="numpy", inline="always")
def ring_reserve(data: NDArray[np.uint8], index: NDArray[np.int64], counters: NDArray[np.int64],
                 length: int) -> int:
    """Make room at the end of the arenas for one record of `length` inner bytes; returns its data offset.

    Both arenas are twice what the capacity can hold, so the live records are moved to the front
    (compacted) at most once per capacity's worth of appends.
    """
    if counters[TAIL] == index.shape[0]:
        head = counters[HEAD]
        live = counters[TAIL] - head
        for k in range(live):  # forward copies: the destination lies before the source
            for c in range(4):
                index[k, c] = index[head + k, c]
        counters[HEAD], counters[TAIL] = 0, live
    if counters[DATA_END] + length > data.shape[0]:
        live = counters[TAIL] - counters[HEAD]
        base = index[counters[HEAD], R_OFFSET] if live else counters[DATA_END]
        size = counters[DATA_END] - base
        for k in range(size):
            data[k] = data[base + k]
        for k in range(counters[HEAD], counters[TAIL]):
            index[k, R_OFFSET] -= base
        counters[DATA_END] = size
    return counters[DATA_END]


@njit(cache=True, error_model="numpy", inline="always")
def ring_commit(index: NDArray[np.int64], counters: NDArray[np.int64], sample: int, length: int,
                is_sample: bool) -> None:
    """Register the record whose inner bytes were written at the reserved offset; drop the oldest to fit."""
    size = length + RECORD_OVERHEAD_BYTES
    tail = counters[TAIL]
    index[tail, R_SAMPLE] = sample
    index[tail, R_OFFSET] = counters[DATA_END]
    index[tail, R_LENGTH] = length
    index[tail, R_IS_SAMPLE] = 1 if is_sample else 0
    counters[TAIL] = tail + 1
    counters[DATA_END] += length
    used = counters[BYTES_USED] + size
    head = counters[HEAD]
    while used > counters[CAPACITY]:
        used -= index[head, R_LENGTH] + RECORD_OVERHEAD_BYTES
        head += 1
    counters[HEAD] = head
    counters[BYTES_USED] = used
    if is_sample and sample >= counters[NEXT_SAMPLE]:
        counters[NEXT_SAMPLE] = sample + 1


@njit(cache=True, error_model="numpy")
def ring_append(data: NDArray[np.uint8], index: NDArray[np.int64], counters: NDArray[np.int64], sample: int,
                inner: bytes, is_sample: bool) -> None:
    """Store one frame (too long for the log: not stored); a SAMPLE moves next_sample past its index."""
    length = len(inner)
    if length + RECORD_OVERHEAD_BYTES > counters[CAPACITY] or length > _LONGEST_INNER:
        return
    at = ring_reserve(data, index, counters, length)
    for k in range(length):
        data[at + k] = inner[k]
    ring_commit(index, counters, sample, length, is_sample)


class LogRing:
    """Records in production order; the oldest are overwritten once `capacity_bytes` is used.

    `first_sample` and `next_sample` are what HEARTBEAT and LOG_RANGE report: the oldest SAMPLE index
    still held and the index the next SAMPLE will get. `data`, `index` and `counters` are the arrays
    compiled code appends to (ring_reserve / ring_commit).
    """

    def __init__(self, capacity_bytes: int = LOG_CAPACITY_BYTES) -> None:
        if capacity_bytes <= 0:
            raise ValueError("capacity_bytes must be positive")
        self.capacity_bytes = capacity_bytes
        self.data = np.zeros(2 * capacity_bytes + 2 * _LONGEST_INNER, np.uint8)
        self.index = np.zeros((2 * (capacity_bytes // _MIN_RECORD_BYTES + 1), 4), np.int64)
        self.counters = np.zeros(N_COUNTERS, np.int64)
        self.counters[CAPACITY] = capacity_bytes
        self._append = direct_entry(ring_append, self.data, self.index, self.counters, 0, b"", True)

    @property
    def bytes_used(self) -> int:
        return int(self.counters[BYTES_USED])

    @property
    def next_sample(self) -> int:
        return int(self.counters[NEXT_SAMPLE])

    @property
    def first_sample(self) -> int:
        """The oldest sample index still held (equals next_sample when the log is empty)."""
        counters = self.counters
        if counters[TAIL] > counters[HEAD]:
            return int(self.index[counters[HEAD], R_SAMPLE])
        return int(counters[NEXT_SAMPLE])

    def __len__(self) -> int:
        return int(self.counters[TAIL] - self.counters[HEAD])

    def append(self, sample: int, inner: bytes, is_sample: bool) -> None:
        """Store one frame; a SAMPLE moves next_sample past its index."""
        self._append(self.data, self.index, self.counters, sample, inner, is_sample)

    def records(self, first_sample: int, end_sample: int, max_samples: int = 0) -> list[LogRecord]:
        """Records whose sample index lies in [first_sample, end_sample), oldest first.

        With max_samples, the range is cut after the sample index of the max_samples-th SAMPLE record, so the
        EPISODE frames of that index come along (SPEC s. 7, LOG_REQUEST bound). A list of copies: the caller
        re-sends it while the program keeps logging into the ring.
        """
        head, tail = int(self.counters[HEAD]), int(self.counters[TAIL])
        if tail == head or end_sample <= first_sample:
            return []
        # Sample indices never decrease along the log.
        at = head + int(np.searchsorted(self.index[head:tail, R_SAMPLE], first_sample, side="left"))
        out: list[LogRecord] = []
        samples, cut = 0, end_sample
        data = self.data
        while at < tail:
            rows = self.index[at:min(at + _ROWS_PER_READ, tail)].tolist()  # a LOG_REQUEST reads a few hundred
            at += len(rows)
            for sample, offset, length, is_sample in rows:
                if sample >= cut:
                    return out
                out.append(LogRecord(sample, data[offset:offset + length].tobytes(), bool(is_sample)))
                if max_samples and is_sample:
                    samples += 1
                    if samples == max_samples:
                        cut = min(cut, sample + 1)
        return out
