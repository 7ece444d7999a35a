"""The agent's signing state on its link (SPEC s. 12): replay mark, nonce, link-id table, the PARAM_SET re-sync."""

from __future__ import annotations

from pathlib import Path
from typing import NamedTuple

from protocol import Frame, SignatureCheck, SignatureVerifier, messages
from protocol.registry import Message
from protocol.signing import RESYNC_NAME, RESYNC_NONCE_FORMAT
from simulator.agent.signing_mark import MarkFile

_SURFACE_ID = messages.Surface.MSG_ID
# The ACK reason of a CMD_SURFACE run without a valid signature or with a stale timestamp (SPEC 1.2 s. 12).
UNVERIFIED_SURFACE = "surfacing without a valid signature: the fail-safe"
RESYNCED = "re-synced: the signing estimate, link ids and mark start again from this frame's timestamp"


def is_resync(message: Message) -> bool:
    """PARAM_SET of index -1 named `resync`: the signed re-sync of SPEC s. 12, not a parameter."""
    return isinstance(message, messages.ParamSet) and message.index == -1 and message.name == RESYNC_NAME


def _named(check: SignatureCheck) -> str:
    return check.name.lower().replace("_", " ")


class SignedCheck(NamedTuple):
    """One signing step's answer: `refused` (the ACK's reason) or, for a CMD_SURFACE, why it runs `unverified`
    (surfacing is the fail-safe state: anyone may make the agent surface, nobody may make it dive)."""

    refused: str = ""
    unverified: str = ""


class LinkSigning:
    """The signing checks of one agent with a key; `mark_file` keeps the mark across restarts (SPEC s. 12).

    The link asks in SPEC s. 5's order (HMAC, then its ACK memory, then the timestamp or the re-sync) and gives
    the time of its own clock each time: a test may swap that clock after the link is made.
    """

    def __init__(self, key: bytes, mark_file: Path | None = None) -> None:
        marks = MarkFile(mark_file) if mark_file is not None else None
        self.verifier = SignatureVerifier(key, floor=marks.read() if marks else -1,
                                          persist=marks.write if marks else None)

    def admits(self, frame: Frame, now_s: float) -> bool:
        """A non-command frame is a sign of life only when validly signed and fresh."""
        return self.verifier.check(frame.inner, now_s) is SignatureCheck.VALID

    def authenticate(self, frame: Frame) -> SignedCheck:
        """Steps 1-2 (SIGNED, long enough, the HMAC right); changes no replay state."""
        check = self.verifier.authenticate(frame.inner)
        if check is SignatureCheck.VALID:
            return SignedCheck()
        if frame.msg_id != _SURFACE_ID:
            return SignedCheck(refused=f"signature {_named(check)}")
        return SignedCheck(unverified=_named(check))

    def admit(self, frame: Frame, now_s: float) -> SignedCheck:
        """Step 4 on an authenticated command: its timestamp is fresh (and the replay state moves on)."""
        check = self.verifier.admit(frame.inner, now_s)
        if check is SignatureCheck.VALID:
            return SignedCheck()
        if frame.msg_id != _SURFACE_ID:  # surfacing is always safe: CMD_SURFACE runs whatever its timestamp
            # a refusal for the timestamp names the nonce a key holder re-syncs with (SPEC s. 12, "Re-sync")
            return SignedCheck(refused=f"signature {_named(check)}; " + RESYNC_NONCE_FORMAT.format(self.verifier.nonce))
        return SignedCheck(unverified=_named(check))

    def resync(self, frame: Frame, now_s: float) -> str:
        """An authenticated re-sync: with the current nonce the replay state starts again from this frame's timestamp
        (the timestamp checks are what it repairs, so they are not made); the refusal's reason otherwise, "" if done."""
        message = frame.message
        assert isinstance(message, messages.ParamSet)
        if message.value != self.verifier.nonce:  # a replayed or stale re-sync: each nonce re-syncs once
            return "stale re-sync nonce; " + RESYNC_NONCE_FORMAT.format(self.verifier.nonce)
        self.verifier.resync(frame.inner, now_s)
        return ""
