"""Writes tests/vectors/frames.jsonl, the golden frames: `python -m tests.vectors.generate`.

Regenerate only on purpose (a new message or an appended field); the tests compare the code against the
checked-in file in both directions, so a layout change that was not meant shows up as a failing test.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from protocol import FrameEncoder, FrameFlag, messages
from protocol.cobs import cobs_decode
from protocol.registry import Message

VECTORS_PATH = Path(__file__).with_name("frames.jsonl")

# (message, extra flags, seq). Values are exact in f32 where the field is f32, so fields survive the round trip.
CASES: list[tuple[Message, int, int]] = [
    (messages.Hello(protocol_version=1, node_kind=1, definitions_hash=0xDEADBEEF, firmware_major=1,
                    firmware_minor=2, firmware_patch=3, node_id=0x00C0FFEE, boot_id=0x89ABCDEF,
                    name="Tauchroboter ü-1"), 0, 0),
    (messages.Hello(protocol_version=1, node_kind=2, definitions_hash=1, node_id=7, boot_id=0xFFFFFFFF,
                    name="ground-station-éè-1234"), 0, 65535),  # a name of exactly 24 bytes, no NUL; seq wrap
    (messages.Heartbeat(uptime_ms=4_294_967_295, mode=1, battery_mv=3700, rx_frames=123456, rx_rejects=3,
                        rx_lost=17, log_first_sample=1000, log_next_sample=9000, episode=42, signing_rejects=0), 0, 1),
    (messages.Timesync(origin_us=1_732_000_000_123_456, receive_us=0, transmit_us=0), 0, 2),
    (messages.Timesync(origin_us=1_732_000_000_123_456, receive_us=18_446_744_073_709_551_615,
                       transmit_us=5_000_001), 0, 3),
    (messages.Ack(cmd_msg_id=0x83, cmd_seq=65535, result=0), 0, 4),
    (messages.Ack(cmd_msg_id=0x8A, cmd_seq=513, result=1, reason="Wert außerhalb 0…2 m"), 0, 5),
    (messages.Text(t_us=12_345_678, severity=2, text="Tiefe −0,5 m? ✓ 深さ"), 0, 6),
    (messages.Text(t_us=1, severity=3, text="é" * 119), 0, 7),  # 238 bytes: the longest TEXT (247-byte payload)
    (messages.Sample(t_us=3_000_000_000, sample=30000, episode=12, step=299, pressure_pa=106226.25,
                     depth_m=0.5, velocity_mps=-0.015625, actuator_deg=65.5, actuator_cmd_deg=130.0, reward=-1.0,
                     state=100, action=1, mode=1), 0, 8),
    (messages.Sample(t_us=2**64 - 1, sample=2**32 - 1, episode=0, step=0, pressure_pa=0.0, depth_m=-0.0078125,
                     velocity_mps=0.0, actuator_deg=0.0, actuator_cmd_deg=0.0, reward=0.0, state=65535, action=255,
                     mode=2), int(FrameFlag.REPLAYED), 65535),
    (messages.EpisodeStart(t_us=987_654_321, episode=13, sample=30001, start_state=57, depth_m=1.25,
                           velocity_mps=-0.0078125, target_depth_m=1.0, z_tol_m=0.5, zdot_tol_mps=0.125,
                           p_explore=0.25), 0, 9),
    (messages.EpisodeEnd(t_us=1_017_654_321, episode=13, sample=30300, reason=2, end_state=100, steps=300,
                         duration_s=30.0, episode_return=-37.0, successes=5), 0, 10),
    (messages.DumpChunk(dump_id=7, kind=3, episode=13, total_bytes=808, offset=224,
                        data=bytes(range(224))), 0, 11),
    (messages.DumpChunk(dump_id=0xFFFFFFFF, kind=1, episode=1, total_bytes=404, offset=174,
                        data=bytes(range(255, 25, -1))), 0, 12),  # 230 bytes: the longest tail that fits
    (messages.ParamValue(index=3, count=24, param_type=5, value=-0.1, minimum=-1e300, maximum=2.5,
                         name="surface_on_link_loss"), 0, 13),
    (messages.LogRange(first_sample=1000, next_sample=9000, replayed=250, bytes_used=524_000,
                       capacity_bytes=524_288), 0, 14),
    (messages.StartLearning(max_episodes=100), 0, 15),
    (messages.Stop(), 0, 16),
    (messages.Pause(), 0, 17),
    (messages.SetTarget(target_depth_m=1.5), 0, 18),
    (messages.Surface(), 0, 65534),
    (messages.Hover(depth_m=-0.25), 0, 19),
    (messages.DumpRequest(kind=4, dump_id=0, offset=0, length=0), 0, 20),
    (messages.DumpRequest(kind=2, dump_id=99, offset=448, length=224), 0, 21),
    (messages.ResetModel(), 0, 22),
    (messages.ParamListRequest(), 0, 23),
    (messages.ParamGet(index=-1, name="target_depth_m"), 0, 24),
    (messages.ParamGet(index=5, name=""), 0, 25),
    (messages.ParamSet(index=-32768, value=-273.15, name="Ölpumpe_ä"), 0, 26),
    (messages.LogRequest(first_sample=1000, end_sample=0xFFFFFFFF), 0, 27),
]


def vector(message: Message, flags: int, seq: int) -> dict[str, Any]:
    """One golden frame: the message's fields, the header, the inner frame and the wire bytes."""
    encoded = FrameEncoder(first_seq=seq).encode(message, flags)
    inner = cobs_decode(encoded.wire[:-1])
    return {
        "name": message.DEFINITION.name,
        "fields": message.to_dict(),
        "flags": inner[1],
        "seq": encoded.seq,
        "inner_hex": inner.hex(),
        "wire_hex": encoded.wire.hex(),
    }


def render() -> str:
    return "".join(json.dumps(vector(*case), ensure_ascii=False) + "\n" for case in CASES)


def main() -> None:
    VECTORS_PATH.write_text(render(), encoding="utf-8")
    print(f"wrote {len(CASES)} vectors to {VECTORS_PATH}")


if __name__ == "__main__":
    main()
