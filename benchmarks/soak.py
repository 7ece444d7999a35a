"""Soak: an hour of agent time against the virtual agent at --speed max with faults on (not a test; run by hand).

    .venv/bin/python benchmarks/soak.py [--agent-hours 1] [--speed max] [--faults "--drop 0.02 --corrupt 0.005"]

Prints frames handled, reconnects, the ground station's memory (RSS) at start, middle and end, and every
SAMPLE missing from the recording (with the agent's own count of what it lost to faults).
"""

from __future__ import annotations

import argparse
import json
import shlex
import signal
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

from groundstation.links import make_link
from groundstation.mcap_io import iter_messages
from groundstation.recording.recorder import Recorder, RecorderConfig
from groundstation.session.agent_session import Session, SessionConfig
from groundstation.session.events import LinkEvent, Received, Sent
from protocol import Mode, compiled
from protocol import messages as m

DEFAULT_FAULTS = "--drop 0.02 --corrupt 0.005 --disconnect-every 600 --blackout-below 1.5"


def rss_mb() -> float:
    for line in Path("/proc/self/status").read_text().splitlines():
        if line.startswith("VmRSS:"):
            return int(line.split()[1]) / 1024
    return float("nan")


class AgentClock:
    """A session listener that follows the agent's clock (its SAMPLE t_us)."""

    def __init__(self) -> None:
        self.agent_s = 0.0
        self.first_s: float | None = None  # agent time of the first live SAMPLE out of IDLE: the soak counts from there
        self.last_sample = 0  # index of the newest live SAMPLE
        self.changed = threading.Event()

    def on_received(self, received: Received) -> None:
        msg = received.message
        # From the first live SAMPLE out of IDLE: before CMD_START the agent idles at --speed max (one cheap step per
        # 0.1 s of agent time), thousands of agent seconds per wall second of the handshake, none of them learning.
        learning = self.first_s is not None or (isinstance(msg, m.Sample) and msg.mode != Mode.IDLE)
        if isinstance(msg, m.Sample) and not received.backfilled and learning:
            self.agent_s = max(self.agent_s, msg.t_us / 1e6)
            self.last_sample = max(self.last_sample, msg.sample)
            if self.first_s is None:
                self.first_s = self.agent_s

    def on_sent(self, sent: Sent) -> None:
        pass

    def on_event(self, event: LinkEvent) -> None:
        pass


def missing_samples(path: Path, last: int) -> tuple[int, list[int], int, int]:
    """(samples held, indices missing between the first held and the last reported, duplicates, the most
    records the agent's on-board log held at once by its HEARTBEATs). Only samples up to `last` count: the
    soak's, not those the agent sent while it was stopped and the backfill waited."""
    held: set[int] = set()
    duplicates = 0
    reported_end = 0
    log_window = 0
    for msg in iter_messages(path, {"/agent/SAMPLE", "/agent/HEARTBEAT"}):
        body = msg.json()
        if msg.topic == "/agent/SAMPLE":
            index = int(body["sample"])
            if index > last:
                continue
            duplicates += index in held
            held.add(index)
        else:
            reported_end = max(reported_end, int(body["log_next_sample"]))
            log_window = max(log_window, int(body["log_next_sample"]) - int(body["log_first_sample"]))
    if not held:
        return 0, [], 0, log_window
    end = min(max(max(held) + 1, reported_end), last + 1)
    return len(held), sorted(set(range(min(held), end)) - held), duplicates, log_window


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--agent-hours", type=float, default=1.0)
    parser.add_argument("--speed", default="max")
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--faults", default=DEFAULT_FAULTS)
    args = parser.parse_args()
    work = Path(tempfile.mkdtemp(prefix="dive-soak-"))
    report = work / "agent-report.json"
    agent = subprocess.Popen(
        [sys.executable, "-m", "simulator", "serve", "--tcp", "127.0.0.1:0", "--speed", args.speed, "--seed",
         str(args.seed), "--report", str(report), *shlex.split(args.faults)],
        stdout=subprocess.PIPE, text=True)
    assert agent.stdout is not None
    url = agent.stdout.readline().strip()
    clock = AgentClock()
    recorder = Recorder(RecorderConfig(directory=work / "rec"))
    session = Session(make_link(url), SessionConfig(), [recorder, clock])
    wall0 = time.monotonic()
    rss: list[tuple[str, float]] = []
    compiled.wait()  # numba's ~60 MB are loaded in the background: the start RSS must include them
    try:
        session.connect()
        session.command(m.StartLearning(max_episodes=0))
        while clock.first_s is None:  # the agent idled at the surface until now: its clock ran ahead
            time.sleep(0.05)
        start_agent_s = clock.first_s
        rss.append(("start", rss_mb()))
        target_s = args.agent_hours * 3600
        halfway = False
        while clock.agent_s - start_agent_s < target_s:
            time.sleep(0.05)  # at --speed max the agent runs thousands of seconds per wall second: look often
            if not halfway and clock.agent_s - start_agent_s >= target_s / 2:
                rss.append(("middle", rss_mb()))
                halfway = True
        soaked_agent_s, soaked_wall_s = clock.agent_s - start_agent_s, time.monotonic() - wall0
        soaked_last = clock.last_sample
        try:
            session.command(m.Stop())
        except Exception as e:  # noqa: BLE001 the soak reports, it does not stop on a lost command
            print(f"stop command: {e}")
        still_missing = session.request_backfill(15.0)
        rss.append(("end", rss_mb()))
    finally:
        session.close()
        recorder.close()
        agent.send_signal(signal.SIGTERM)
        agent.wait(30)
    wall_s = time.monotonic() - wall0
    stats = session.decoder.stats
    agent_report = json.loads(report.read_text())
    held, missing, duplicates, log_window = missing_samples(recorder.paths[-1], soaked_last)
    print(f"agent time       {soaked_agent_s:,.0f} s at --speed {args.speed} in {soaked_wall_s:,.1f} s wall (soak); "
          f"{clock.agent_s - start_agent_s:,.0f} s and {wall_s:,.1f} s wall when the session closed "
          "(after CMD_STOP and the backfill wait)")
    print(f"faults           {args.faults}")
    print(f"frames handled   {stats.frames:,} received ({stats.lost:,} lost by seq, {stats.rejects:,} rejected), "
          f"{session.stats.tx_frames:,} sent, {session.stats.retries:,} retries")
    print(f"reconnects       {session.stats.reconnects} (agent saw {agent_report['connections']} connections)")
    print("ground RSS       " + ", ".join(f"{name} {value:.1f} MB" for name, value in rss)
          + f"  (end/start {rss[-1][1] / rss[0][1]:.3f})")
    print(f"agent lost       {agent_report['out']['dropped']:,} dropped, {agent_report['out']['corrupted']:,} "
          f"corrupted, {agent_report['out']['blacked_out']:,} blacked out")
    print(f"samples          {held:,} recorded up to the soak's last (#{soaked_last:,}), {duplicates} duplicated, "
          f"{len(missing)} missing; {session.stats.backfilled:,} backfilled in all (session says {still_missing} "
          "still missing when it closed)")
    if missing:
        print(f"missing samples  {missing[:50]}{' ...' if len(missing) > 50 else ''}")
        # A lost SAMPLE can be backfilled only while the agent's 512 KiB log still holds it; at --speed max that
        # is a short stretch of wall time, so a missing sample here is one the log had overwritten, not one lost
        # by the ground station, unless the window below is long against the session's retry times.
        per_wall_s = held / soaked_wall_s if soaked_wall_s else 0.0
        print(f"on-board log     held at most {log_window:,} samples: {log_window / per_wall_s:.1f} s of wall time "
              f"at the soak's {per_wall_s:,.0f} samples/s" if per_wall_s else "")
    print(f"recording        {recorder.paths[-1]}")


if __name__ == "__main__":
    main()
