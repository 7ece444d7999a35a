"""The diving agent's wire protocol: frames, messages and a streaming decoder (standard library only, no I/O)."""

from protocol import messages as messages
from protocol.decoder import DecoderStats, Frame, StreamDecoder
from protocol.encoder import EncodedFrame, FrameEncoder
from protocol.enums import (
    PROTOCOL_VERSION,
    AckResult,
    Action,
    DumpKind,
    EndReason,
    FrameFlag,
    Mode,
    NodeKind,
    ParamType,
    Severity,
)
from protocol.errors import CobsError, FrameError, PayloadError, ProtocolError, UnknownMessageError
from protocol.registry import (
    Direction,
    Message,
    MessageDef,
    definitions,
    definitions_hash,
    message_class,
    message_class_by_name,
)
from protocol.signing import SignatureCheck, SignatureVerifier, Signer, SigningError

__all__ = [
    "PROTOCOL_VERSION", "AckResult", "Action", "CobsError", "DecoderStats", "Direction", "DumpKind",
    "EncodedFrame", "EndReason", "Frame", "FrameEncoder", "FrameError", "FrameFlag", "Message", "MessageDef",
    "Mode", "NodeKind", "ParamType", "PayloadError", "ProtocolError", "Severity", "SignatureCheck",
    "SignatureVerifier", "Signer", "SigningError", "StreamDecoder", "UnknownMessageError",
    "definitions", "definitions_hash", "message_class", "message_class_by_name",
    "messages",
]
