"""Log replay: LOG_REQUEST re-sends the logged frames exactly as they went out live, flagged REPLAYED (SPEC.md 7)."""

from __future__ import annotations

from groundstation.check.errors import CheckSkipped
from groundstation.check.probe import Probe, result_name
from groundstation.check.registry import check, expect
from protocol import AckResult, FrameFlag
from protocol import messages as m
from protocol.decoder import Frame

SECTION = "7 Data streams and the on-board log"
REPLAY_BOUND = 512  # one LOG_REQUEST replays at most 512 samples (decisions: issue 13 amplification bound)
_LOGGED = (m.Sample, m.EpisodeStart, m.EpisodeEnd)
_REPLAYED = int(FrameFlag.REPLAYED)


def _replay(probe: Probe, first: int, end: int, size_hint: int = 0) -> tuple[list[Frame], m.LogRange]:
    ex = probe.command(m.LogRequest(first_sample=first, end_sample=end))
    expect(ex.result == AckResult.ACCEPTED, f"LOG_REQUEST [{first}, {end}): {result_name(ex.result)}")
    found = probe.wait_message(m.LogRange, ex.ack_at, probe.timeouts.reply_s + size_hint / 1000)
    expect(found is not None, f"LOG_REQUEST [{first}, {end}): no LOG_RANGE")
    assert found is not None
    replayed = [f for f in probe.frames(ex.ack_at, found[0]) if f.flags & _REPLAYED]
    return replayed, found[1]


def _live_samples(probe: Probe, count: int) -> dict[int, Frame]:
    """The newest `count` consecutive live SAMPLEs by sample index (waiting for them if needed)."""
    seen: dict[int, Frame] = {}

    def enough(_: object) -> bool:
        for f in probe.frames(max(probe.end - 5000, 0)):
            if isinstance(f.message, m.Sample) and not f.flags & _REPLAYED:
                seen[f.message.sample] = f
        newest = max(seen, default=-1)
        return newest >= 0 and all(newest - i in seen for i in range(count))

    start = probe.end
    expect(probe.wait(enough, start, probe.timeouts.heartbeat_s * count) is not None,
           f"{count} consecutive live SAMPLEs did not arrive")
    newest = max(seen)
    return {i: seen[i] for i in range(newest - count + 1, newest + 1)}


@check("log.replay_identical", SECTION, """LOG_REQUEST [first_sample, end_sample): the agent ACKs, re-sends the
       logged records whose sample index lies in the range, in the order they were produced, then sends one
       LOG_RANGE. A replayed frame carries its original msg_id and payload, the REPLAYED flag and a new seq (it
       counts in the sequence like any frame).""")
def replay_identical(probe: Probe) -> str:
    live = _live_samples(probe, 3)
    first, end = min(live), max(live) + 1
    lost_before = probe.decoder.stats.lost + probe.decoder.stats.duplicates
    replayed, log_range = _replay(probe, first, end)
    samples = [(f, f.message.sample) for f in replayed if isinstance(f.message, m.Sample)]
    indices = [index for _, index in samples]
    expect(indices == list(range(first, end)), f"replayed samples {indices}, wanted {list(range(first, end))}")
    for f, index in samples:
        original = live[index]
        expect(f.msg_id == original.msg_id and f.payload == original.payload,
               f"replayed SAMPLE {index} differs from the live one")
        expect(f.seq != original.seq, f"replayed SAMPLE {index} kept its old seq")
    expect(all(isinstance(f.message, _LOGGED) for f in replayed), "a replayed frame that is not SAMPLE/EPISODE_*")
    expect(log_range.replayed == len(replayed), f"LOG_RANGE replayed {log_range.replayed}, {len(replayed)} came")
    gaps = probe.decoder.stats.lost + probe.decoder.stats.duplicates - lost_before
    expect(gaps == 0, f"the replayed frames broke the agent's seq counter ({gaps} lost or duplicate)")
    return f"samples [{first}, {end}) replayed byte-identical with REPLAYED set"


@check("log.empty_request", SECTION, """end_sample ≤ first_sample → ACCEPTED, no frames, LOG_RANGE with replayed
       0.""")
def empty_request(probe: Probe) -> str:
    for first, end in ((10, 10), (10, 5)):
        replayed, log_range = _replay(probe, first, end)
        expect(not replayed and log_range.replayed == 0,
               f"LOG_REQUEST [{first}, {end}): {len(replayed)} frames, LOG_RANGE replayed {log_range.replayed}")
    return "[10, 10) and [10, 5): nothing replayed, LOG_RANGE replayed 0"


@check("log.range", SECTION, """capacity_bytes = 524 288 (a virtual agent may be configured smaller). bytes_used is
       the sum of (1 + L) over the records held. HEARTBEAT reports log_first_sample and log_next_sample.""")
def log_range(probe: Probe) -> str:
    hb = probe.counters()
    _, r = _replay(probe, 0, 0)
    expect(r.first_sample <= r.next_sample, f"first_sample {r.first_sample} > next_sample {r.next_sample}")
    expect(r.next_sample >= hb.log_next_sample, f"LOG_RANGE next_sample {r.next_sample} behind the HEARTBEAT's "
           f"{hb.log_next_sample}")
    expect(0 < r.capacity_bytes <= 524_288, f"capacity_bytes {r.capacity_bytes}")
    expect(r.bytes_used <= r.capacity_bytes, f"bytes_used {r.bytes_used} > capacity_bytes {r.capacity_bytes}")
    return (f"samples [{r.first_sample}, {r.next_sample}), {r.bytes_used} of {r.capacity_bytes} bytes")


@check("log.bound_512", SECTION, """Bound: one request replays at most 512 SAMPLE records and the EPISODE frames
       whose sample index lies among them: with c the sample index of the 512th SAMPLE replayed, the range is cut
       at c + 1. LOG_RANGE replayed is the number of frames re-sent.""")
def bound_512(probe: Probe) -> str:
    hb = probe.counters()
    held = hb.log_next_sample - hb.log_first_sample
    if held < REPLAY_BOUND + 50:
        raise CheckSkipped(f"the log holds {held} samples, fewer than {REPLAY_BOUND + 50}")
    first = hb.log_next_sample - (REPLAY_BOUND + 50)
    replayed, log_range = _replay(probe, first, 0xFFFFFFFF, size_hint=REPLAY_BOUND * 60)
    samples = [f.message.sample for f in replayed if isinstance(f.message, m.Sample)]
    expect(len(samples) <= REPLAY_BOUND, f"{len(samples)} samples replayed for one request, at most {REPLAY_BOUND}")
    expect(samples == list(range(first, first + len(samples))), "the replayed samples are not the first ones asked")
    expect(log_range.replayed == len(replayed), f"LOG_RANGE replayed {log_range.replayed}, {len(replayed)} came")
    return f"{len(samples)} samples for a request of {REPLAY_BOUND + 50}+"


@check("log.gone", SECTION, """Samples no longer held (overwritten) are simply not replayed; LOG_RANGE
       first_sample tells the ground what is gone.""")
def gone(probe: Probe) -> str:
    hb = probe.counters()
    if hb.log_first_sample == 0:
        raise CheckSkipped("the log still holds sample 0 (nothing overwritten yet)")
    replayed, log_range = _replay(probe, 0, min(hb.log_first_sample, 10))
    expect(not replayed, f"{len(replayed)} frames replayed for samples older than the log")
    expect(log_range.first_sample >= hb.log_first_sample, f"LOG_RANGE first_sample {log_range.first_sample}")
    return f"samples before {log_range.first_sample} are gone and were not replayed"
