"""Runs the main job (`dive run`) against a faulty virtual agent and compares what the agent injected with what
the ground station counted and recorded."""

from __future__ import annotations

import json
import subprocess
from bisect import bisect_right
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from mcap.reader import make_reader

from groundstation.recording.held_frames import RAW_RX_UNUSED_TOPIC
from tests.reliability.recordings import Recording, dive, read
from tests.simulator.agent_client import running

HELLO_ID = 0x01


@dataclass
class FaultRun:
    done: subprocess.CompletedProcess[str]
    report: dict[str, Any]  # the agent's --report
    recording: Recording
    path: Path
    connections: list[list[int]]  # per ground connection: the agent seqs received, in order
    hellos: list[int]  # where in connections[0] the agent's HELLOs are (each resets sequence tracking, SPEC s. 1)
    unused: list[int]  # where in connections[0] the frames from /raw/rx_unused are

    @property
    def final_link(self) -> dict[str, Any]:
        return self.recording.link[-1]["link"]


def run_against_faults(tmp_path: Path, faults: list[str], speed: str = "max", episodes: int = 2,
                       seed: int = 7) -> FaultRun:
    report = tmp_path / "agent-report.json"
    out = tmp_path / "rec"
    # The hardware preset's short failing episodes keep each case to seconds (paper: 300 s successes).
    with running("--tcp", "127.0.0.1:0", "--preset", "hardware", "--speed", speed, "--seed", str(seed),
                 "--report", str(report), *faults) as agent:
        done = dive("run", agent.address, "--episodes", str(episodes), "--out", str(out))
    files = sorted(out.glob("*.mcap"))
    assert done.returncode == 0 and len(files) == 1, done.stderr
    assert "Traceback" not in done.stderr
    connections, hellos, unused = _rx_by_connection(files[0])
    return FaultRun(done, json.loads(report.read_text()), read(files[0]), files[0], connections, hellos, unused)


def _rx_by_connection(path: Path) -> tuple[list[list[int]], list[int], list[int]]:
    """The seqs of every frame received, in file order (one list: the agent's connections are told apart by seq),
    and the positions of the HELLOs and of the unused frames among them. Every frame: /raw/rx and /raw/rx_unused,
    the frames the session decoded (their seqs counted) but did not use, such as a LOG_REQUEST range's replays of
    samples it already held; without them a loss just before such replays at a connection's end looked invisible,
    and the ground's exact count read as 1-6 too many under heavy load."""
    seqs: list[int] = []
    hellos: list[int] = []
    unused: list[int] = []
    with path.open("rb") as f:
        for _, channel, message in make_reader(f).iter_messages(topics=["/raw/rx", RAW_RX_UNUSED_TOPIC],
                                                                log_time_order=False):
            seqs.append(message.data[2] | message.data[3] << 8)
            if message.data[4] == HELLO_ID:
                hellos.append(len(seqs) - 1)
            if channel.topic == RAW_RX_UNUSED_TOPIC:
                unused.append(len(seqs) - 1)
    return [seqs], hellos, unused


def _connection_spans(out: dict[str, Any]) -> list[tuple[int, int, int]]:
    """(base seq, start, end) of each agent connection on one axis of seqs counted from the run's first: from each
    connection's length and the gap to the next, both below 65 536, never from two bases' difference (a connection
    that sent a long backfill held 30 115 seqs, and two bases 32 768 or more apart read as a step back)."""
    spans, position, previous_end = [], 0, None
    for (base, *_), end in zip(out["lost_by_connection"], out["connection_end_seqs"], strict=True):
        if previous_end is not None:
            position += (base - previous_end) & 0xFFFF
        spans.append((base, position, position + ((end - base) & 0xFFFF)))
        position, previous_end = spans[-1][2], end
    return spans


def _positions(seqs: list[int], spans: list[tuple[int, int, int]]) -> list[int | None]:
    """Each received seq on the spans' axis, in file order: in the connection it came on (the first, from the
    current one on, whose span holds it); None for one no connection holds."""
    out: list[int | None] = []
    current = 0
    for seq in seqs:
        for k in range(current, len(spans)):
            base, start, end = spans[k]
            distance = (seq - base) & 0xFFFF
            if distance < end - start:
                current = k
                out.append(start + distance)
                break
        else:
            out.append(None)
    return out


def visible_losses(run: FaultRun) -> int:
    """Frames the agent lost to faults that the ground could see as a seq gap: between two frames it received
    within the same connection (the ground starts counting afresh on every reconnect), the later one not a HELLO
    (any HELLO resets sequence tracking before it is counted, SPEC.md section 1)."""
    return len(_visible_lost(run))


def _visible_lost(run: FaultRun) -> set[int]:
    """The lost frames visible_losses counts, as positions on the spans' axis."""
    out = run.report["out"]
    spans = _connection_spans(out)
    received = _positions(run.connections[0], spans)
    hello_at = {received[i] for i in run.hellos}
    visible = set()
    for (base, start, end), (_, *lost) in zip(spans, out["lost_by_connection"], strict=True):
        mine = sorted(p for p in received if p is not None and start <= p < end)
        for p in (start + ((seq - base) & 0xFFFF) for seq in lost):
            index = bisect_right(mine, p)
            if 0 < index < len(mine) and mine[index] not in hello_at:
                visible.add(p)
    return visible


def _recounted_lost(run: FaultRun) -> set[int]:
    """The seq gaps the ground's decoder counts on the frames the recording holds, in their order (as positions on
    the spans' axis): afresh on each connection and at each HELLO; a late one among them is taken back."""
    spans = _connection_spans(run.report["out"])
    received = _positions(run.connections[0], spans)
    hellos = set(run.hellos)
    counted: set[int] = set()
    expected: int | None = None
    connection = -1
    for i, p in enumerate(received):
        if p is None:
            continue
        k = next(k for k, (_, start, end) in enumerate(spans) if start <= p < end)
        if k != connection or i in hellos:
            connection, expected = k, None
        if expected is not None and p > expected:
            counted.update(range(expected, p))
        elif expected is not None and p < expected:
            counted.discard(p)
            continue
        expected = p + 1
    return counted


def loss_mismatch(run: FaultRun) -> str:
    """Why the ground's loss count and visible_losses differ: both figures, the gaps the ground counts on the
    recorded frames (the same count unless it decoded frames the recording lacks), which lost seqs one side has
    and the other not, and the recorded seqs around the first of those (H: a HELLO, u: from /raw/rx_unused)."""
    link = run.final_link
    visible, recounted = _visible_lost(run), _recounted_lost(run)
    spans = _connection_spans(run.report["out"])
    received = _positions(run.connections[0], spans)
    only_ground, only_visible = sorted(recounted - visible), sorted(visible - recounted)
    lines = [f"ground rx_lost {link['rx_lost']} (rx_frames {link['rx_frames']}), visible {len(visible)}, "
             f"recounted on the {len(received)} recorded frames {len(recounted)}; "
             f"connections (base, start, end) {spans}",
             f"counted not visible {only_ground[:20]}, visible not counted {only_visible[:20]}"]
    first = min(only_ground[:1] + only_visible[:1], default=None)
    if first is not None:
        at = min(range(len(received)), key=lambda i: abs((received[i] or 0) - first))
        hellos, unused = set(run.hellos), set(run.unused)
        around = [f"{received[i]}{'H' if i in hellos else ''}{'u' if i in unused else ''}"
                  for i in range(max(0, at - 12), min(len(received), at + 12))]
        lines.append(f"recorded positions around {first}: {' '.join(around)}")
    return "\n".join(lines)
