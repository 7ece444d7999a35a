"""Recordings made in tests by the real recorder from hand-built frames: HELLOs and SAMPLEs with chosen indices."""

from __future__ import annotations

from pathlib import Path

from groundstation.recording.recorder import Recorder, RecorderConfig
from groundstation.session.events import Received
from protocol import Frame, Message, Mode, definitions_hash
from protocol import messages as m
from protocol.frame import build_inner


def received(message: Message, seq: int, host_ns: int = 1_700_000_000_000_000_000) -> Received:
    inner = build_inner(0, seq, message.DEFINITION.msg_id, message.pack())
    return Received(Frame(0, seq, message.DEFINITION.msg_id, message, inner), host_ns + seq * 1000, None, False)


def hello(boot_id: int = 5) -> m.Hello:
    return m.Hello(protocol_version=1, node_kind=1, definitions_hash=definitions_hash(), node_id=7, boot_id=boot_id,
                   name="tank")


def sample(index: int, t_us: int | None = None) -> m.Sample:
    return m.Sample(t_us=t_us if t_us is not None else 1_000_000 + 20_000 * index, sample=index, episode=1, step=index,
                    pressure_pa=106000.0, depth_m=0.5, velocity_mps=0.0, actuator_deg=65.0, actuator_cmd_deg=65.0,
                    reward=-1.0, state=50, action=0, mode=int(Mode.LEARNING))


def make_recording(path: Path, boots: tuple[int, ...] = (5,), samples: int = 300, flush_every: int = 0) -> Path:
    """A recording made by the real recorder: per boot a HELLO then `samples` samples (indices from 0)."""
    recorder = Recorder(RecorderConfig(path=path, flush_period_s=3600))
    seq = 0
    for boot_id in boots:
        recorder.on_received(received(hello(boot_id), seq))
        for i in range(samples):
            seq += 1
            recorder.on_received(received(sample(i), seq))
            if flush_every and i % flush_every == flush_every - 1:
                assert recorder._writer is not None
                recorder._writer.flush()  # a chunk per `flush_every` samples, as the 1 s flush makes them
    recorder.close()
    return path
