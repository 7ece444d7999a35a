"""Every message of protocol version 1: the one definition table the wire layout, SPEC.md and hash come from.

Ids: 0x00-0x1F link and system (both ways), 0x20-0x7F agent to ground, 0x80-0xFF ground to agent.
Append-only: a field is only ever added at the end of a payload (before nothing), never moved.
"""

from __future__ import annotations

from protocol.fields import F32, F64, I16, U8, U16, U32, U64, Name, TailBytes, TailText, wire
from protocol.registry import Direction, Message, message

# ---------------------------------------------------------------- link and system, both ways


@message(0x01, "HELLO", Direction.BOTH)
class Hello(Message):
    """Sent unprompted by each side when a link comes up; the receiver checks version and hash."""

    protocol_version: U8 = wire("protocol major version; 1")
    node_kind: U8 = wire("1 = agent, 2 = ground station (NodeKind)")
    definitions_hash: U32 = wire("hash of the message definition table (SPEC.md, Definitions hash)")
    firmware_major: U8 = wire("sender's software version, major")
    firmware_minor: U8 = wire("sender's software version, minor")
    firmware_patch: U8 = wire("sender's software version, patch")
    node_id: U32 = wire("agent id (serial number) or ground station id")
    boot_id: U32 = wire("random, new after every reboot; a change means the peer restarted")
    name: Name = wire("human-readable node name, UTF-8", default="")


@message(0x02, "HEARTBEAT", Direction.BOTH)
class Heartbeat(Message):
    """Once per second of the sender's clock, each way; counters as SPEC.md section 4 defines them."""

    uptime_ms: U32 = wire("sender's time since boot", "ms")
    mode: U8 = wire("agent's Mode; 0 from the ground")
    battery_mv: U16 = wire("battery voltage; 0 from the ground", "mV")
    rx_frames: U32 = wire("frames that passed CRC and version checks and were acted on (refused commands too)")
    rx_rejects: U32 = wire("chunks dropped since boot: oversize, COBS, runt, CRC, incompatible, unknown id, malformed")
    rx_lost: U32 = wire("frames lost by sequence number since boot (the sum of the gaps)")
    log_first_sample: U32 = wire("oldest SAMPLE index still in the on-board log; 0 from the ground")
    log_next_sample: U32 = wire("index the next SAMPLE will get; 0 from the ground")
    episode: U32 = wire("current or last episode number; 0 from the ground")
    signing_rejects: U32 = wire("commands answered UNAUTHORIZED since boot")


@message(0x03, "TIMESYNC", Direction.BOTH)
class Timesync(Message):
    """Clock sync round trip: a request has receive_us = transmit_us = 0; a reply echoes origin_us, transmit_us != 0."""

    origin_us: U64 = wire("requester's clock when it sent the request", "us")
    receive_us: U64 = wire("responder's clock when the request arrived; 0 in a request", "us")
    transmit_us: U64 = wire("responder's clock when it sent the reply; 0 in a request", "us")


@message(0x04, "ACK", Direction.BOTH)
class Ack(Message):
    """The answer to every command: result 0 accepts it, anything else is a NACK with a reason."""

    cmd_msg_id: U8 = wire("msg_id of the command answered")
    cmd_seq: U16 = wire("seq of the command's frame")
    result: U8 = wire("AckResult; 0 = accepted")
    reason: TailText = wire("optional human-readable reason, UTF-8", default="")


@message(0x05, "TEXT", Direction.BOTH)
class Text(Message):
    """A log line."""

    t_us: U64 = wire("sender's clock", "us")
    severity: U8 = wire("Severity: 0 debug, 1 info, 2 warning, 3 error")
    text: TailText = wire("the line, UTF-8, at most 238 bytes", default="")


# ---------------------------------------------------------------- agent to ground


@message(0x20, "SAMPLE", Direction.AGENT_TO_GROUND)
class Sample(Message):
    """One control step (rates by mode: SPEC.md section 7); also kept in the on-board log."""

    t_us: U64 = wire("agent clock at the step", "us")
    sample: U32 = wire("global sample index, +1 per SAMPLE since boot; the on-board log's key")
    episode: U32 = wire("episode number (0 before the first)")
    step: U32 = wire("step within the episode")
    pressure_pa: F32 = wire("raw pressure reading", "Pa")
    depth_m: F32 = wire("depth from pressure, positive down", "m")
    velocity_mps: F32 = wire("observer's velocity estimate, positive down", "m/s")
    actuator_deg: F32 = wire("counted stepper angle, motor side of the gear (0..130, larger = more volume)", "deg")
    actuator_cmd_deg: F32 = wire("commanded gear angle", "deg")
    reward: F32 = wire("reward received this step (0 outside learning)")
    state: U16 = wire("discrete learner state; S-1 = terminal")
    action: U8 = wire("Action: 0 decrease volume, 1 increase volume, 255 none")
    mode: U8 = wire("Mode")


@message(0x21, "EPISODE_START", Direction.AGENT_TO_GROUND)
class EpisodeStart(Message):
    """A learning episode begins (the learner takes over)."""

    t_us: U64 = wire("agent clock", "us")
    episode: U32 = wire("episode number")
    sample: U32 = wire("index of the episode's first SAMPLE")
    start_state: U16 = wire("discrete state at the start")
    depth_m: F32 = wire("depth at the start", "m")
    velocity_mps: F32 = wire("velocity estimate at the start", "m/s")
    target_depth_m: F32 = wire("target depth z_d", "m")
    z_tol_m: F32 = wire("half-height of the learning region", "m")
    zdot_tol_mps: F32 = wire("velocity bound of the learning region", "m/s")
    p_explore: F32 = wire("exploration probability in this episode (0..1)")


@message(0x22, "EPISODE_END", Direction.AGENT_TO_GROUND)
class EpisodeEnd(Message):
    """A learning episode ends: failure (left the region), success (time limit reached) or aborted."""

    t_us: U64 = wire("agent clock", "us")
    episode: U32 = wire("episode number")
    sample: U32 = wire("index of the episode's last SAMPLE")
    reason: U8 = wire("EndReason: 1 failure, 2 success, 3 aborted")
    end_state: U16 = wire("discrete state at the end")
    steps: U32 = wire("learner steps taken")
    duration_s: F32 = wire("time inside the learning region", "s")
    episode_return: F32 = wire("sum of rewards of the episode")
    successes: U32 = wire("successful episodes so far, this one included")


@message(0x23, "DUMP_CHUNK", Direction.AGENT_TO_GROUND, chunked=True)
class DumpChunk(Message):
    """One piece of a dump snapshot (value function, policy, Q values or model counts)."""

    dump_id: U32 = wire("snapshot id, never 0; a new snapshot gets a new id")
    kind: U8 = wire("DumpKind: 1 values, 2 policy, 3 Q values, 4 counts")
    episode: U32 = wire("episodes completed when the snapshot was taken")
    total_bytes: U32 = wire("size of the whole snapshot", "B")
    offset: U32 = wire("position of `data` in the snapshot", "B")
    data: TailBytes = wire("0 to 230 bytes of the snapshot (a sender puts at most 224)", default=b"")


@message(0x24, "PARAM_VALUE", Direction.AGENT_TO_GROUND)
class ParamValue(Message):
    """One parameter: sent for PARAM_LIST, PARAM_GET and, with the value applied, after PARAM_SET."""

    index: U16 = wire("parameter index, 0..count-1")
    count: U16 = wire("number of parameters the agent has")
    param_type: U8 = wire("ParamType: 1 bool, 2 u8, 3 i32, 4 u32, 5 f32")
    value: F64 = wire("value as stored; for F32 the stored f32 widened exactly to f64")
    minimum: F64 = wire("smallest accepted value")
    maximum: F64 = wire("largest accepted value")
    name: Name = wire("parameter name, with its unit as a suffix (e.g. target_depth_m)", default="")


@message(0x25, "LOG_RANGE", Direction.AGENT_TO_GROUND)
class LogRange(Message):
    """What the on-board log holds; sent when a LOG_REQUEST replay is finished."""

    first_sample: U32 = wire("oldest SAMPLE index held")
    next_sample: U32 = wire("index the next SAMPLE will get")
    replayed: U32 = wire("frames re-sent for the request just finished")
    bytes_used: U32 = wire("log bytes in use", "B")
    capacity_bytes: U32 = wire("log size (524 288 on a real agent's two M24M02 EEPROMs)", "B")


# ---------------------------------------------------------------- ground to agent: commands (all ACKed)


@message(0x80, "CMD_START", Direction.GROUND_TO_AGENT, ack=True)
class StartLearning(Message):
    """Start (or resume) learning: RECOVERING to a random start, then LEARNING."""

    max_episodes: U32 = wire("stop after this many more episodes; 0 = the max_episodes parameter")


@message(0x81, "CMD_STOP", Direction.GROUND_TO_AGENT, ack=True)
class Stop(Message):
    """Stop learning or hovering (the episode is aborted) and return to the surface; no effect in IDLE, SURFACING."""


@message(0x82, "CMD_PAUSE", Direction.GROUND_TO_AGENT, ack=True)
class Pause(Message):
    """Pause learning: the episode is aborted and the recovery controller holds the current depth."""


@message(0x83, "CMD_SET_TARGET", Direction.GROUND_TO_AGENT, ack=True)
class SetTarget(Message):
    """Set the target depth z_d of learning."""

    target_depth_m: F32 = wire("new target depth", "m")


@message(0x84, "CMD_SURFACE", Direction.GROUND_TO_AGENT, ack=True)
class Surface(Message):
    """Emergency surface: maximum volume now, in any mode."""


@message(0x85, "CMD_HOVER", Direction.GROUND_TO_AGENT, ack=True)
class Hover(Message):
    """Hold a depth in [0, 2.5] m with the recovery controller (no learning)."""

    depth_m: F32 = wire("depth to hold", "m")


@message(0x86, "CMD_DUMP", Direction.GROUND_TO_AGENT, ack=True)
class DumpRequest(Message):
    """Ask for a dump, or for a range of one already taken (to fill missing chunks)."""

    kind: U8 = wire("DumpKind")
    dump_id: U32 = wire("0 = take a new snapshot; else re-send from that snapshot")
    offset: U32 = wire("first byte wanted", "B")
    length: U32 = wire("bytes wanted; 0 = to the end", "B")


@message(0x87, "CMD_RESET_MODEL", Direction.GROUND_TO_AGENT, ack=True)
class ResetModel(Message):
    """Forget model, values, policy, episode count and successes (not allowed while LEARNING)."""


@message(0x88, "PARAM_LIST", Direction.GROUND_TO_AGENT, ack=True)
class ParamListRequest(Message):
    """Ask for every parameter: the ACK, then one PARAM_VALUE per parameter in index order."""


@message(0x89, "PARAM_GET", Direction.GROUND_TO_AGENT, ack=True)
class ParamGet(Message):
    """Ask for one parameter, by index or (index = -1) by name."""

    index: I16 = wire("parameter index, or -1 to look it up by name")
    name: Name = wire("parameter name when index = -1", default="")


@message(0x8A, "PARAM_SET", Direction.GROUND_TO_AGENT, ack=True)
class ParamSet(Message):
    """Set one parameter: ACK then PARAM_VALUE, or a NACK (BAD_VALUE, NOT_ALLOWED_IN_MODE) and nothing else."""

    index: I16 = wire("parameter index, or -1 to look it up by name")
    value: F64 = wire("new value; refused unless finite, in range, integral for integer types")
    name: Name = wire("parameter name when index = -1", default="")


@message(0x8B, "LOG_REQUEST", Direction.GROUND_TO_AGENT, ack=True)
class LogRequest(Message):
    """Re-send logged SAMPLE and EPISODE frames with sample index in [first_sample, end_sample)."""

    first_sample: U32 = wire("first SAMPLE index wanted")
    end_sample: U32 = wire("one past the last wanted; 0xFFFFFFFF = up to the newest")
