"""The protocol's exception base and its specific errors."""

from __future__ import annotations


class ProtocolError(ValueError):
    """Base of every error raised by the protocol package (never raised by StreamDecoder.feed)."""


class CobsError(ProtocolError):
    """A chunk that is not valid canonical COBS."""


class FrameError(ProtocolError):
    """An inner frame that is too short, fails its CRC, or is incompatible."""


class UnknownMessageError(ProtocolError, KeyError):
    """A message id or name that the definition table does not hold."""


class PayloadError(ProtocolError):
    """A message whose fields do not fit its wire layout (out of range, too long)."""
