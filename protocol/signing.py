"""Command authentication (SPEC.md section 12): a truncated HMAC-SHA256 trailer with a replay-proof timestamp."""

from __future__ import annotations

import hashlib
import hmac
import re
import time
from collections import OrderedDict
from collections.abc import Callable
from dataclasses import dataclass, field, fields
from enum import IntEnum

from protocol.enums import FrameFlag
from protocol.errors import ProtocolError
from protocol.frame import HEADER, MIN_INNER, TRAILER_SIZE

KEY_SIZE = 32
SIGNATURE_SIZE = 6
LINK_ID_SIZE = 1
TIMESTAMP_SIZE = 6  # u48 little-endian
TIMESTAMP_UNIT_US = 10
EPOCH_2015_UNIX_S = 1_420_070_400  # 2015-01-01 00:00:00 UTC, MAVLink 2's signing epoch
TIMESTAMP_MAX = (1 << 48) - 1
# A link id the receiver has not seen since boot is refused if its first timestamp lies further than this behind
# the receiver's estimate of "now" (MAVLink 2 uses the same minute).
NEW_LINK_WINDOW_S = 60.0
# Once the receiver has an estimate, a timestamp further than this ahead of it is refused (too new), so that one
# frame from a clock far ahead cannot lock every later frame out as a replay.
FUTURE_WINDOW_S = 60.0
# One accepted frame moves the estimate at most this far past where it was (issue 25 L5): a clock ahead but inside
# FUTURE_WINDOW_S cannot ratchet the estimate a minute per frame until every new link id is refused as too old.
ESTIMATE_STEP_S = 10.0
LINK_IDS_HELD = 16  # replay state kept for this many link ids; the least recently accepted one is forgotten
# The highest accepted timestamp survives a reboot: the receiver stores mark = accepted + this whenever an accepted
# timestamp passes the stored mark (at most one non-volatile write per 10 s) and refuses timestamps <= the mark.
MARK_AHEAD_S = 10.0
# The signed re-sync (SPEC.md section 12): a validly signed PARAM_SET of index -1 with this name and the agent's
# current nonce as its value resets the receiver's replay state to the frame's timestamp. The agent tells its nonce
# at the end of every refusal for the timestamp (replayed, too old, too new), in RESYNC_NONCE_FORMAT.
RESYNC_NAME = "resync"
RESYNC_NONCE_FORMAT = "re-sync nonce {:08x}"
_RESYNC_NONCE = re.compile(r"re-sync nonce ([0-9a-f]{8})\b")
_TICKS_PER_S = 1_000_000 // TIMESTAMP_UNIT_US
_SIGNED = int(FrameFlag.SIGNED)


class SigningError(ProtocolError):
    """A key that is not 32 bytes, or key text that is not 64 hex digits."""


class SignatureCheck(IntEnum):
    """What a receiver concluded about one frame's signature; only VALID may run a command."""

    VALID = 0
    UNSIGNED = 1  # flag bit 4 (SIGNED) clear
    TRUNCATED = 2  # flag bit 4 (SIGNED) set, but the frame is too short to hold a trailer
    BAD_SIGNATURE = 3  # wrong key, or any bit of header, payload, link id or timestamp changed
    REPLAYED = 4  # timestamp not above the last accepted one of its link id, or not above the persisted mark
    TOO_OLD = 5  # a link id new since boot whose timestamp is over NEW_LINK_WINDOW_S behind the estimate
    TOO_NEW = 6  # a timestamp over FUTURE_WINDOW_S ahead of the estimate


def check_key(key: bytes) -> bytes:
    """The key itself if it is 32 bytes; SigningError otherwise."""
    if len(key) != KEY_SIZE:
        raise SigningError(f"a signing key is {KEY_SIZE} bytes, got {len(key)}")
    return bytes(key)


def parse_key(text: str) -> bytes:
    """A key from its file text: 64 hex digits (whitespace around them ignored)."""
    digits = text.strip()
    try:
        key = bytes.fromhex(digits)
    except ValueError as e:
        raise SigningError(f"a key file holds {2 * KEY_SIZE} hex digits: {e}") from e
    return check_key(key)


def format_key(key: bytes) -> str:
    """The file text of a key: 64 lower-case hex digits and a newline."""
    return check_key(key).hex() + "\n"


def timestamp_from_unix_ns(unix_ns: int) -> int:
    """A signing timestamp: 10 µs units since 2015-01-01 UTC, clamped to u48."""
    ticks = (unix_ns // 1000 - EPOCH_2015_UNIX_S * 1_000_000) // TIMESTAMP_UNIT_US
    return min(max(ticks, 0), TIMESTAMP_MAX)


def resync_nonce(reason: str) -> int | None:
    """The re-sync nonce an agent's refusal names (SPEC.md section 12), or None."""
    found = _RESYNC_NONCE.search(reason)
    return int(found.group(1), 16) if found else None


def new_nonce() -> int:
    """A fresh random re-sync nonce, never 0 (0 is what an unset field reads as)."""
    import secrets  # here, not at the top: `dive --help` imports protocol and must stay quick (issue 14)

    return secrets.randbits(32) or 1


def signature(key: bytes, signed_part: bytes) -> bytes:
    """The first 6 bytes of HMAC-SHA256(key, everything in the inner frame before the signature)."""
    return hmac.new(key, signed_part, hashlib.sha256).digest()[:SIGNATURE_SIZE]


class Signer:
    """One sender's signing state: key, link id and a timestamp that only ever increases."""

    def __init__(self, key: bytes, link_id: int, clock_ns: Callable[[], int] = time.time_ns) -> None:
        if not 0 <= link_id <= 0xFF:
            raise SigningError(f"link id {link_id} is not a u8")
        self._key = check_key(key)
        self.link_id = link_id
        self._clock_ns = clock_ns
        self._last_timestamp = -1

    def next_timestamp(self) -> int:
        # Wall time, but never equal to or below the previous one: two frames in the same 10 µs, or the host clock
        # stepping back, must not make the receiver refuse our own next frame as a replay.
        stamp = max(timestamp_from_unix_ns(self._clock_ns()), self._last_timestamp + 1)
        self._last_timestamp = min(stamp, TIMESTAMP_MAX)
        return self._last_timestamp

    def trailer(self, body: bytes) -> bytes:
        """The 13-byte trailer for `body` = header (SIGNED already set) + payload."""
        head = bytes([self.link_id]) + self.next_timestamp().to_bytes(TIMESTAMP_SIZE, "little")
        return head + signature(self._key, body + head)


@dataclass(slots=True)
class VerifierStats:
    """Frames checked by result."""

    valid: int = 0
    unsigned: int = 0
    truncated: int = 0
    bad_signature: int = 0
    replayed: int = 0
    too_old: int = 0
    too_new: int = 0
    resyncs: int = 0  # signed re-syncs accepted

    @property
    def rejects(self) -> int:
        return self.truncated + self.bad_signature + self.replayed + self.too_old + self.too_new

    def as_dict(self) -> dict[str, int]:
        return {f.name: getattr(self, f.name) for f in fields(self)}


@dataclass
class SignatureVerifier:
    """The receiver's side: checks a frame's trailer and keeps the replay state (the last timestamp per link id).

    `now_s` is the receiver's link clock in seconds (any monotonic clock in real time); it only advances the
    estimate of the current timestamp between accepted frames. `floor` is the mark persisted before this boot
    (-1: none): timestamps at or below it are refused. `persist` is called with each new mark to store
    (SPEC.md section 12).
    An agent runs authenticate() and admit() apart, its ACK memory between them; check() runs both.
    """

    key: bytes = field(repr=False)  # never in a repr (a log line, a traceback's locals)
    stats: VerifierStats = field(default_factory=VerifierStats)
    floor: int = -1
    persist: Callable[[int], None] | None = None
    mark: int = field(init=False)  # the mark last persisted (floor until the first one)
    nonce: int = field(init=False)  # what the next signed re-sync must carry: new at boot and after each re-sync
    _last_by_link: OrderedDict[int, int] = field(default_factory=OrderedDict)
    _best_timestamp: int | None = None
    _best_at_s: float = 0.0

    def __post_init__(self) -> None:
        self.key = check_key(self.key)
        self.mark = self.floor
        self.nonce = new_nonce()

    def check(self, inner: bytes, now_s: float) -> SignatureCheck:
        """Check the inner frame (CRC included, already CRC-checked); a VALID frame moves the replay state on."""
        result = self.authenticate(inner)
        return self.admit(inner, now_s) if result is SignatureCheck.VALID else result

    def authenticate(self, inner: bytes) -> SignatureCheck:
        """Steps 1-2: SIGNED set, long enough, and the HMAC right (VALID); changes no replay state."""
        result = self._authenticate(inner)
        if result is not SignatureCheck.VALID:
            self._count(result)
        return result

    def admit(self, inner: bytes, now_s: float) -> SignatureCheck:
        """Step 4 on an authenticated frame: its timestamp is fresh (VALID, and the replay state moves on)."""
        result = self._admit(inner, now_s)
        self._count(result)
        return result

    def resync(self, inner: bytes, now_s: float) -> None:
        """Accept an authenticated re-sync (its nonce already matched): the frame's timestamp becomes the estimate,
        its link id the only one in the table, and the floor and mark start from it; the nonce is renewed, so the
        same frame cannot re-sync again (SPEC.md section 12, "Re-sync")."""
        link_id, stamp = self._trailer(inner)
        self._last_by_link = OrderedDict({link_id: stamp})
        self._best_timestamp, self._best_at_s = stamp, now_s
        self.floor = stamp
        self.mark = min(stamp + int(MARK_AHEAD_S * _TICKS_PER_S), TIMESTAMP_MAX)
        if self.persist is not None:
            self.persist(self.mark)  # lower than the stored one: a reboot must not bring the old lock-out back
        self.nonce = new_nonce()
        self.stats.resyncs += 1

    def estimate(self, now_s: float) -> int | None:
        """The receiver's estimate of the sender's current timestamp, or None before the first valid frame."""
        if self._best_timestamp is None:
            return None
        return self._best_timestamp + int(max(now_s - self._best_at_s, 0.0) * _TICKS_PER_S)

    def _count(self, result: SignatureCheck) -> None:
        name = result.name.lower()
        setattr(self.stats, name, getattr(self.stats, name) + 1)

    def _authenticate(self, inner: bytes) -> SignatureCheck:
        if len(inner) < HEADER.size or not inner[1] & _SIGNED:
            return SignatureCheck.UNSIGNED
        if len(inner) < MIN_INNER + TRAILER_SIZE:
            return SignatureCheck.TRUNCATED
        sig_start = len(inner) - 2 - SIGNATURE_SIZE
        if not hmac.compare_digest(signature(self.key, inner[:sig_start]), inner[sig_start:-2]):
            return SignatureCheck.BAD_SIGNATURE
        return SignatureCheck.VALID

    @staticmethod
    def _trailer(inner: bytes) -> tuple[int, int]:
        """(link id, timestamp) of a signed inner frame."""
        sig_start = len(inner) - 2 - SIGNATURE_SIZE
        link_id = inner[sig_start - TIMESTAMP_SIZE - LINK_ID_SIZE]
        return link_id, int.from_bytes(inner[sig_start - TIMESTAMP_SIZE : sig_start], "little")

    def _admit(self, inner: bytes, now_s: float) -> SignatureCheck:
        link_id, stamp = self._trailer(inner)
        last = self._last_by_link.get(link_id)
        if (last is not None and stamp <= last) or stamp <= self.floor:
            return SignatureCheck.REPLAYED
        estimate = self.estimate(now_s)
        if estimate is not None:
            if last is None and stamp < estimate - int(NEW_LINK_WINDOW_S * _TICKS_PER_S):
                return SignatureCheck.TOO_OLD
            if stamp > estimate + int(FUTURE_WINDOW_S * _TICKS_PER_S):
                return SignatureCheck.TOO_NEW
        self._last_by_link[link_id] = stamp
        self._last_by_link.move_to_end(link_id)
        if len(self._last_by_link) > LINK_IDS_HELD:
            self._last_by_link.popitem(last=False)  # evicted: "not seen since boot" again
        if estimate is None or stamp > estimate:  # the frame keeps its own timestamp above; the estimate a bounded step
            step = int(ESTIMATE_STEP_S * _TICKS_PER_S)
            self._best_timestamp = stamp if estimate is None else min(stamp, estimate + step)
            self._best_at_s = now_s
        if stamp > self.mark:
            self.mark = min(stamp + int(MARK_AHEAD_S * _TICKS_PER_S), TIMESTAMP_MAX)
            if self.persist is not None:
                self.persist(self.mark)
        return SignatureCheck.VALID
