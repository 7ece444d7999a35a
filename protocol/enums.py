"""Enumerated field values shared by the agent and the ground station."""

from __future__ import annotations

from enum import IntEnum, IntFlag

PROTOCOL_VERSION = 1  # the major version on the wire (frame `ver`, HELLO protocol_version)
# SPEC.md's version: the minor number is the document's, never sent, so 1.0-1.2 peers share PROTOCOL_VERSION.
SPEC_VERSION = "1.3"


class FrameFlag(IntFlag):
    """The frame's flags byte. Bits 0-3 may be ignored by a receiver; bits 4-7 unknown => drop."""

    ACK_REQUESTED = 0x01  # the sender wants an ACK (set on every command)
    REPLAYED = 0x02  # re-sent from the agent's on-board log, not live
    # Bit 4, an "incompatible" bit (SPEC 1.1 on): a receiver that does not know it drops signed frames instead of
    # reading the trailer as payload, as MAVLink 2 does with its incompat flag. Bit 2 (1.0's SIGNED) is reserved.
    SIGNED = 0x10  # a signature trailer ends the payload (see SPEC.md, signing)


KNOWN_INCOMPATIBLE_FLAGS = 0x10  # of bits 4-7, versions 1.1 and 1.2 define bit 4 (SIGNED)
# The incompatible bits (4-7) this version does not know: a frame with one of them set is dropped.
INCOMPATIBLE_FLAGS_MASK = 0xF0 & ~KNOWN_INCOMPATIBLE_FLAGS


class NodeKind(IntEnum):
    AGENT = 1
    GROUND = 2


class Mode(IntEnum):
    """The agent's operating mode (SPEC.md documents the transitions)."""

    IDLE = 0  # at the surface, actuator at neutral, waiting
    LEARNING = 1  # the learner acts every control period
    RECOVERING = 2  # the recovery controller brings the agent back into the learning region
    HOVER = 3  # the recovery controller holds a commanded depth
    SURFACING = 4  # maximum volume until the surface is reached, then IDLE
    PAUSED = 5  # learning paused: the recovery controller holds the current depth


class Action(IntEnum):
    DECREASE_VOLUME = 0  # a1: less volume, less buoyancy, sinks
    INCREASE_VOLUME = 1  # a2: more volume, more buoyancy, rises
    NONE = 255  # no learner action this step (recovery, hover, idle)


class EndReason(IntEnum):
    FAILURE = 1  # entered the terminal state (left the learning region)
    SUCCESS = 2  # stayed in the learning region for the success time (a truncation)
    ABORTED = 3  # stopped by a command, a surfacing or a fault


class AckResult(IntEnum):
    """Result code of an ACK; anything but ACCEPTED is a NACK."""

    ACCEPTED = 0
    BAD_VALUE = 1  # a field is out of range or unknown (e.g. parameter index)
    NOT_ALLOWED_IN_MODE = 2  # valid, but not in the agent's current mode
    UNSUPPORTED = 3  # the agent does not implement this command
    BUSY = 4  # try again later
    STALE = 5  # dump snapshot no longer held: request again with dump_id 0
    UNAUTHORIZED = 6  # signing required and missing, wrong or replayed
    FAILED = 7  # accepted but could not be carried out


# The TEXT (severity WARNING) an agent sends its current connection when a new one replaces it (SPEC.md s. 3): the
# old ground then knows it lost the link to another ground, and stops instead of taking it back.
LINK_TAKEN_TEXT = "link taken by another ground"


class Severity(IntEnum):
    DEBUG = 0
    INFO = 1
    WARNING = 2
    ERROR = 3


class DumpKind(IntEnum):
    """What a dump carries; all arrays little-endian, state-major, S = number of states."""

    VALUES = 1  # f32[S]: v(s)
    POLICY = 2  # u8[S]: greedy action per state (Action), 255 where untried
    Q_VALUES = 3  # f32[S][2]: Q(s, a1), Q(s, a2)  (101 x 2 x 4 = 808 bytes)
    COUNTS = 4  # u16[2][S][S]: C(s, s', a) by action, then state, then successor


class ParamType(IntEnum):
    BOOL = 1
    U8 = 2
    I32 = 3
    U32 = 4
    F32 = 5
