"""The on-board log's record format and the LOG_REQUEST bound (SPEC.md section 7)."""

from __future__ import annotations

from simulator.agent.log_ring import LogRing


def _fill(ring: LogRing, samples: int) -> None:
    """SAMPLE records 0..samples-1, with an EPISODE_START before sample 10 and an EPISODE_END after sample 19."""
    for index in range(samples):
        if index == 10:
            ring.append(index, b"S" * 49, False)  # EPISODE_START carries its first sample's index
        ring.append(index, b"x" * 55, True)
        if index == 19:
            ring.append(index, b"E" * 42, False)  # EPISODE_END carries its last sample's index


def test_bytes_used_is_one_length_byte_plus_the_inner_frame_per_record_and_whole_records_are_dropped() -> None:
    ring = LogRing(capacity_bytes=10 * 56)
    assert ring.first_sample == ring.next_sample == 0  # empty: first = next
    _fill(ring, 12)
    held = ring.records(0, 2**32)
    assert ring.bytes_used <= ring.capacity_bytes and ring.bytes_used == sum(len(r.inner) + 1 for r in held)
    assert ring.next_sample == 12 and ring.first_sample > 0


def test_a_request_replays_at_most_n_samples_and_the_episode_frames_of_their_indices() -> None:
    ring = LogRing()
    _fill(ring, 40)
    first = ring.records(0, 40, max_samples=10)
    assert [r.sample for r in first if r.is_sample] == list(range(10))
    assert not [r for r in first if not r.is_sample]  # the EPISODE_START of sample 10 goes with sample 10
    second = ring.records(10, 40, max_samples=10)
    assert [r.inner[:1] for r in second[:2]] == [b"S", b"x"] and second[-1].inner[:1] == b"E"
    assert [r.sample for r in second if r.is_sample] == list(range(10, 20))
    assert ring.records(5, 5, max_samples=10) == [] and ring.records(9, 3) == []
