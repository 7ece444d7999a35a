"""Synthetic agent traffic for the view tests and the replay benchmark: frames as a session receives them."""

from __future__ import annotations

import json
import math
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from mcap.writer import CompressionType, Writer

from groundstation.recording.recorder import Recorder, RecorderConfig
from groundstation.session.events import EventKind, LinkEvent, Received, SessionListener
from protocol import DumpKind, EndReason, Frame, FrameFlag, Message, Mode, definitions_hash
from protocol import messages as m
from protocol.frame import build_inner

STATES = 101
START_NS = 1_700_000_000_000_000_000  # host clock at the first frame


@dataclass(frozen=True)
class Traffic:
    """What the agent sent and the ground station recorded beside it (1 Hz link statistics)."""

    frames: list[Received]
    link: list[tuple[int, dict[str, Any]]]

    @property
    def samples(self) -> int:
        return sum(isinstance(r.message, m.Sample) for r in self.frames)


def generate(duration_s: float, rate_hz: float = 10.0, seed: int = 1, backfill_every: int = 0) -> Traffic:
    """Episodes that get longer as the agent 'learns', a VALUES and POLICY dump after each, 1 Hz heartbeats."""
    rng = np.random.default_rng(seed)
    frames: list[Received] = []
    link: list[tuple[int, dict[str, Any]]] = []
    seq = 0

    def add(message: Message, t_s: float, flags: int = 0) -> None:
        nonlocal seq
        inner = build_inner(flags, seq, message.DEFINITION.msg_id, message.pack())
        frame = Frame(flags, seq, message.DEFINITION.msg_id, message, inner)
        seq = (seq + 1) & 0xFFFF
        frames.append(Received(frame, START_NS + int(t_s * 1e9), None, bool(flags & FrameFlag.REPLAYED)))

    add(m.Hello(protocol_version=1, node_kind=1, definitions_hash=definitions_hash(), node_id=7, boot_id=11,
                name="synthetic"), 0.0)
    steps = int(duration_s * rate_hz)
    episode, step, episode_len, sample_in_episode = 1, 0, 20, 0
    target, depth, velocity = 0.5, 0.5, 0.0
    add(m.EpisodeStart(t_us=0, episode=1, sample=0, start_state=55, depth_m=depth, velocity_mps=0.0,
                       target_depth_m=target, z_tol_m=0.1, zdot_tol_mps=0.04, p_explore=0.1), 0.0)
    dump_id = 1
    for i in range(steps):
        t_s = i / rate_hz
        velocity = 0.9 * velocity + rng.normal(0, 0.002)
        depth = min(max(depth + velocity / rate_hz, target - 0.099), target + 0.099)
        action = int(rng.integers(0, 2))
        state = min(int((depth - target + 0.1) / 0.02), 9) * 10 + min(max(int((velocity + 0.04) / 0.008), 0), 9)
        flags = FrameFlag.REPLAYED if backfill_every and i % backfill_every == 0 else 0
        add(m.Sample(t_us=int(t_s * 1e6), sample=i, episode=episode, step=step, pressure_pa=101325 + 9810 * depth,
                     depth_m=depth, velocity_mps=velocity, actuator_deg=65 + 10 * math.sin(t_s),
                     actuator_cmd_deg=65.0, reward=-abs(depth - target), state=state, action=action,
                     mode=Mode.LEARNING), t_s, flags)
        step += 1
        sample_in_episode += 1
        if i % int(rate_hz) == 0:
            add(m.Heartbeat(uptime_ms=int(t_s * 1e3), mode=Mode.LEARNING, battery_mv=3900, episode=episode), t_s)
            link.append((START_NS + int(t_s * 1e9),
                         {"link": {"loss_fraction": 0.01, "rtt_median_ms": 12.0 + rng.random()}, "clock": {}}))
        if sample_in_episode >= episode_len:
            success = episode_len >= 3000
            add(m.EpisodeEnd(t_us=int(t_s * 1e6), episode=episode, sample=i,
                             reason=EndReason.SUCCESS if success else EndReason.FAILURE, end_state=100, steps=step,
                             duration_s=step / rate_hz, episode_return=-float(step) * 0.01, successes=0), t_s)
            add(m.Text(t_us=int(t_s * 1e6), severity=1, text=f"episode {episode} done"), t_s)
            values = (-rng.random(STATES) * 10).astype("<f4").tobytes()
            policy = rng.integers(0, 2, STATES, dtype=np.uint8).tobytes()
            for kind, data in ((DumpKind.VALUES, values), (DumpKind.POLICY, policy)):
                for offset in range(0, len(data), 224):
                    add(m.DumpChunk(dump_id=dump_id, kind=kind, episode=episode, total_bytes=len(data),
                                    offset=offset, data=data[offset : offset + 224]), t_s)
                dump_id += 1
            episode += 1
            step, sample_in_episode = 0, 0
            episode_len = min(int(episode_len * 1.3), 3000)
            add(m.EpisodeStart(t_us=int(t_s * 1e6), episode=episode, sample=i + 1, start_state=55, depth_m=depth,
                               velocity_mps=velocity, target_depth_m=target, z_tol_m=0.1, zdot_tol_mps=0.04,
                               p_explore=0.1), t_s)
    return Traffic(frames, link)


def write_mcap(path: Path, traffic: Traffic, chunk_size: int = 64 * 1024) -> None:
    """The recording format of TEAM.md (raw frames, link statistics, an event), written with mcap directly."""
    with path.open("wb") as stream:
        writer = Writer(stream, chunk_size=chunk_size, compression=CompressionType.NONE)
        writer.start(profile="", library="tests")
        raw = writer.register_channel("/raw/rx", "diving-agent-frame-v1", 0)
        schema = writer.register_schema("diving_agent.link", "jsonschema", b"{}")
        link = writer.register_channel("/link", "json", schema)
        event = writer.register_channel("/event", "json", schema)
        writer.add_message(event, log_time=START_NS, publish_time=START_NS,
                           data=json.dumps({"kind": "connected", "detail": "synthetic", "data": {}}).encode())
        stats = iter(traffic.link)
        pending = next(stats, None)
        for received in traffic.frames:
            while pending is not None and pending[0] <= received.host_time_ns:
                writer.add_message(link, log_time=pending[0], publish_time=pending[0],
                                   data=json.dumps(pending[1]).encode())
                pending = next(stats, None)
            writer.add_message(raw, log_time=received.host_time_ns, publish_time=received.host_time_ns,
                               data=received.frame.inner)
        writer.finish()



def play_session(traffic: Traffic, listeners: Iterable[SessionListener]) -> None:
    """What a session hands its listeners: CONNECTED, every frame, the 1 Hz STATS events."""
    listeners = list(listeners)
    events = [LinkEvent(EventKind.CONNECTED, START_NS, "synthetic")]
    stats = iter(traffic.link)
    pending = next(stats, None)
    for received in traffic.frames:
        while pending is not None and pending[0] <= received.host_time_ns:
            events.append(LinkEvent(EventKind.STATS, pending[0], data=pending[1]))
            pending = next(stats, None)
        for event in events:
            for listener in listeners:
                listener.on_event(event)
        events.clear()
        for listener in listeners:
            listener.on_received(received)


def record(
    traffic: Traffic, path: Path, listeners: Iterable[SessionListener] = (), flush_period_s: float = 1.0
) -> Path:
    """Record the traffic with the ground station's real recorder (and feed other listeners beside it)."""
    recorder = Recorder(RecorderConfig(path=path, flush_period_s=flush_period_s))
    try:
        play_session(traffic, [recorder, *listeners])
    finally:
        recorder.close()
    return path
