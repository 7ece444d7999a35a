"""Which SAMPLE indices the ground holds, as merged half-open ranges, and which are missing."""

from __future__ import annotations

import bisect


class SampleRanges:
    """A set of integers kept as sorted, disjoint [start, end) ranges (samples arrive mostly in order)."""

    def __init__(self) -> None:
        self._starts: list[int] = []
        self._ends: list[int] = []

    def __len__(self) -> int:
        return sum(e - s for s, e in zip(self._starts, self._ends, strict=True))

    def __contains__(self, index: int) -> bool:
        i = bisect.bisect_right(self._starts, index) - 1
        return i >= 0 and index < self._ends[i]

    @property
    def first(self) -> int | None:
        return self._starts[0] if self._starts else None

    def ranges(self) -> list[tuple[int, int]]:
        """The [start, end) ranges held, in order."""
        return list(zip(self._starts, self._ends, strict=True))

    @property
    def end(self) -> int | None:
        """One past the highest index held."""
        return self._ends[-1] if self._ends else None

    def add(self, index: int) -> bool:
        """Add one index; False if it was already held."""
        if self._ends and index == self._ends[-1]:  # the common case: the next sample in order
            self._ends[-1] += 1
            return True
        i = bisect.bisect_right(self._starts, index) - 1
        if i >= 0 and index < self._ends[i]:
            return False
        if i >= 0 and index == self._ends[i]:
            self._ends[i] += 1
        else:
            i += 1
            self._starts.insert(i, index)
            self._ends.insert(i, index + 1)
        if i + 1 < len(self._starts) and self._ends[i] == self._starts[i + 1]:
            self._ends[i] = self._ends.pop(i + 1)
            self._starts.pop(i + 1)
        return True

    def missing(self, start: int | None = None, end: int | None = None) -> list[tuple[int, int]]:
        """Missing [start, end) ranges between start (default: first held) and end (default: end held)."""
        if not self._starts:
            return [(start, end)] if start is not None and end is not None and end > start else []
        lo = self._starts[0] if start is None else start
        hi = self._ends[-1] if end is None else end
        gaps: list[tuple[int, int]] = []
        cursor = lo
        for s, e in zip(self._starts, self._ends, strict=True):
            if s > cursor:
                gaps.append((cursor, min(s, hi)))
            cursor = max(cursor, e)
            if cursor >= hi:
                break
        if cursor < hi:
            gaps.append((cursor, hi))
        return [(a, b) for a, b in gaps if b > a]


class EpisodeFrames:
    """Which EPISODE_START / EPISODE_END frames the ground holds, and where a lost one lies in the on-board log.

    A lost episode frame leaves no gap in the SAMPLE indices, so it is found another way: EPISODE_START carries the
    index of its episode's first LEARNING sample and EPISODE_END that of its last (SPEC.md s. 7), and the agent
    sends each right beside that sample. A LEARNING sample of an episode whose START never came, or a later sample
    after an episode whose END never came, shows the frame was lost; the log holds it under that sample's index.
    """

    def __init__(self) -> None:
        self.starts: set[int] = set()
        self.ends: set[int] = set()
        self._learning: dict[int, tuple[int, int]] = {}  # episode -> (first, last) LEARNING sample index seen
        self._latest_sample = -1
        self._generation = 0

    def saw_generation(self, generation: int) -> None:
        """A learner restart (SPEC 1.3 s. 6) numbers the episodes from 1 again: what is looked for starts afresh, or
        the new learner's episode 1 would pass for the old one's, its lost frames never asked for."""
        if generation and self._generation and generation != self._generation:
            self.starts.clear()
            self.ends.clear()
            self._learning.clear()
        self._generation = generation or self._generation

    def saw_sample(self, sample: int, episode: int, learning: bool) -> None:
        self._latest_sample = max(self._latest_sample, sample)
        if learning:
            first, last = self._learning.pop(episode, (sample, sample))
            self._learning[episode] = (min(first, sample), max(last, sample))  # the newest last in the dict's order
            if len(self._learning) > EPISODES_TRACKED:  # an agent naming a new episode in every SAMPLE: bounded
                del self._learning[next(iter(self._learning))]

    def missing(self) -> list[tuple[int, int]]:
        """[start, end) sample ranges whose replay brings back the lost episode frames."""
        ranges = []
        for episode, (first, last) in self._learning.items():
            if episode not in self.starts:
                ranges.append((first, first + 1))
            if episode not in self.ends and self._latest_sample > last:
                ranges.append((last, last + 1))
        return ranges


REQUEST_SAMPLES = 512  # the agent replays at most 512 samples per LOG_REQUEST (SPEC.md 1.1): ask in pieces
# The most SAMPLEs an on-board log can hold: 512 KiB (SPEC.md s. 7) of records of 56 bytes or more is ~9 400; this
# bound leaves 7x room. The log window an agent claims is believed only this far past the samples seen, so one
# HEARTBEAT claiming a next index near 2^32 plans at most MAX_LOG_SAMPLES / REQUEST_SAMPLES requests (issue 25 C3).
MAX_LOG_SAMPLES = 65536
EPISODES_TRACKED = 64  # episodes whose START / END frames are still looked for (the log holds far fewer)


class BackfillPlanner:
    """Decides which LOG_REQUEST ranges to send: every gap the agent still holds, asked again until it comes.

    `known_end` comes from the agent's HEARTBEAT and LOG_RANGE (log_next_sample): every sample below it was sent
    before, so on an in-order stream a hole below it is a real loss, not a frame in flight. `log_first` is where the
    agent's on-board log now begins: a hole below it is lost for good, and only then is it called lost. A hole
    inside the log is asked for again with a growing wait (retry_after_s, x1.5 each time, at most max_wait_s), for
    as long as the log holds it (issue 13 item 4), in pieces of at most REQUEST_SAMPLES.
    """

    def __init__(self, retry_after_s: float = 1.0, max_wait_s: float = 4.0, merge_below: int = 32,
                 per_round: int = 16) -> None:
        self.held = SampleRanges()
        self.known_end = 0
        self.log_first = 0
        self.episodes = EpisodeFrames()
        self._requested: dict[int, tuple[int, float]] = {}  # first sample of a range -> (attempts, when)
        self._retry_after_s = retry_after_s
        self._max_wait_s = max_wait_s
        self._merge_below = merge_below
        self._per_round = per_round
        self.end_limit: int | None = None  # the run's end (final backfill): nothing at or above it is wanted

    def reset(self) -> None:
        """The agent rebooted: sample indices start again from 0."""
        self.__init__(self._retry_after_s, self._max_wait_s, self._merge_below, self._per_round)  # type: ignore[misc]

    def saw_log_window(self, first_sample: int, next_sample: int) -> None:
        """The agent's claim (HEARTBEAT, LOG_RANGE), believed only as far as the samples seen make possible: its log
        ends at most MAX_LOG_SAMPLES past the highest sample received, and begins at or below its end."""
        next_sample = self.believed_end(next_sample)
        self.log_first = min(first_sample, next_sample)
        self.known_end = max(self.known_end, next_sample)
        if self.end_limit is not None:
            self.known_end = min(self.known_end, self.end_limit)

    def believed_end(self, next_sample: int) -> int:
        """The end of the agent's log it claims, as far as the samples seen make it possible (at most MAX_LOG_SAMPLES
        past the highest received). The run's end (end_limit) does not cut it: that limits what is wanted, not what
        the agent may send, and a SAMPLE after the run's end is a true one (recorded raw)."""
        # before any sample a claim is believed as far as a log from index 0 could reach: a lie near 2^32 in the first
        # HEARTBEAT once reached the run's last line as 4 294 966 578 samples not backfilled (issue 38 N8)
        return min(next_sample, (self.held.end or 0) + MAX_LOG_SAMPLES)

    def finish_at(self) -> int:
        """The run is over: want nothing from the index the agent has reached now on; returns that index."""
        self.end_limit = max(self.known_end, self.held.end or 0)
        return self.end_limit

    def missing(self) -> list[tuple[int, int]]:
        if self.held.first is None:
            return []
        held_end = self.held.end or 0
        # known_end was believed from samples seen then; a log ends at most MAX_LOG_SAMPLES past what is held now
        end = max(min(self.known_end, held_end + MAX_LOG_SAMPLES), held_end)
        return self.held.missing(end=end if self.end_limit is None else min(end, self.end_limit))

    def lost(self) -> int:
        """Missing samples the agent's log no longer holds (below its first sample): gone for good."""
        return sum(min(b, self.log_first) - a for a, b in self.missing() if a < self.log_first)

    def fetchable(self) -> list[tuple[int, int]]:
        """Missing ranges (samples and episode frames) the agent's log still holds: none below its first sample, nor
        more than MAX_LOG_SAMPLES below its end (no log holds more, whatever an agent says)."""
        ranges = []
        floor = max(self.log_first, self.known_end - MAX_LOG_SAMPLES)
        for start, end in sorted(self.missing() + self.episodes.missing()):
            start = max(start, floor)
            if end > start:
                ranges.append((start, end))
        return ranges

    def pending(self) -> bool:
        """Anything the agent still holds left to fetch: samples, or episode frames (not in `missing()`)."""
        return bool(self.fetchable())

    def retry_now(self) -> None:
        """Forget the waits: the next due() asks for everything still missing (the run's final backfill)."""
        self._requested = {start: (attempts, -1e9) for start, (attempts, _) in self._requested.items()}

    def due(self, now_s: float) -> list[tuple[int, int]]:
        """Ranges to request now: merged when close, cut into REQUEST_SAMPLES pieces, each after its wait."""
        merged: list[tuple[int, int]] = []
        for start, end in self.fetchable():
            if merged and start - merged[-1][1] < self._merge_below and end - merged[-1][0] <= REQUEST_SAMPLES:
                merged[-1] = (merged[-1][0], max(end, merged[-1][1]))
            else:
                merged.extend((a, min(a + REQUEST_SAMPLES, end)) for a in range(start, end, REQUEST_SAMPLES))
        due = []
        for rng in merged:
            attempts, when = self._requested.get(rng[0], (0, -1e9))
            wait = min(self._max_wait_s, self._retry_after_s * 1.5 ** max(0, attempts - 1))
            if attempts == 0 or now_s - when >= wait:
                self._requested[rng[0]] = (attempts + 1, now_s)
                due.append(rng)
                if len(due) >= self._per_round:
                    break
        if len(self._requested) > 4 * len(merged) + 64:  # forget ranges that were filled
            starts = {a for a, _ in merged}
            self._requested = {k: v for k, v in self._requested.items() if k in starts}
        return due
