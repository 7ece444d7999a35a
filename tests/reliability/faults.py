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
    connections, hellos = _rx_by_connection(files[0])
    return FaultRun(done, json.loads(report.read_text()), read(files[0]), files[0], connections, hellos)


def _rx_by_connection(path: Path) -> tuple[list[list[int]], list[int]]:
    """The seqs of /raw/rx frames in file order (one list: the agent's connections are told apart by seq), and
    the positions of the HELLOs among them."""
    seqs: list[int] = []
    hellos: list[int] = []
    with path.open("rb") as f:
        for _, _, message in make_reader(f).iter_messages(topics=["/raw/rx"], log_time_order=False):
            seqs.append(message.data[2] | message.data[3] << 8)
            if message.data[4] == HELLO_ID:
                hellos.append(len(seqs) - 1)
    return [seqs], hellos


def _unwrap(seqs: list[int], base: int) -> list[int]:
    """Seqs as distances from `base`, counting wraps of the u16 (consecutive seqs are less than 32768 apart)."""
    out, position, previous = [], 0, base
    for seq in seqs:
        step = (seq - previous) & 0xFFFF
        position += step - 0x10000 if step >= 0x8000 else step
        previous = seq
        out.append(position)
    return out


def visible_losses(run: FaultRun) -> int:
    """Frames the agent lost to faults that the ground could see as a seq gap: between two frames it received
    within the same connection (the ground starts counting afresh on every reconnect), the later one not a HELLO
    (any HELLO resets sequence tracking before it is counted, SPEC.md section 1)."""
    out = run.report["out"]
    bases = [c[0] for c in out["lost_by_connection"]]
    origin = bases[0]
    starts = _unwrap(bases, origin)
    ends = [start + ((end - base) & 0xFFFF) for start, base, end in zip(starts, bases, out["connection_end_seqs"],
                                                                         strict=True)]
    received = _unwrap(run.connections[0], origin)
    hello_at = {received[i] for i in run.hellos}
    total = 0
    for start, base, end, (_, *lost) in zip(starts, bases, ends, out["lost_by_connection"], strict=True):
        mine = sorted(p for p in received if start <= p < end)
        # from the connection's own first seq: unwrapped from the run's first one, a lost seq more than 32 768 past
        # it read as negative, and a long run's later connections lost their counts (780 seen, 507 counted)
        for p in (start + distance for distance in _unwrap(lost, base)):
            index = bisect_right(mine, p)
            if 0 < index < len(mine) and mine[index] not in hello_at:
                total += 1
    return total
