"""Commands in flight: sent, waiting for their ACK, retried with the same seq (SPEC.md section 5)."""

from __future__ import annotations

import threading
from dataclasses import dataclass, field

from groundstation.errors import AgentBusy, CommandError, CommandMayHaveRun
from protocol import AckResult, Message
from protocol import messages as m


class Latch:
    """A one-shot event: set() once from any thread, wait() returns at once after it.

    A command's wake-up is on its round trip: threading.Event builds a Condition (5-6 us) and its set() and
    wait() each take the condition's lock and juggle a waiter lock in Python; this is one lock, taken at
    creation and released by set(), the waiter's acquire() returning in C.
    """

    __slots__ = ("_lock", "_unreleased")

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._lock.acquire()
        self._unreleased = [self._lock]  # list.pop is atomic: of two threads setting at once, one releases

    def set(self) -> None:
        try:
            lock = self._unreleased.pop()
        except IndexError:
            return
        lock.release()

    def is_set(self) -> bool:
        return not self._unreleased

    def wait(self, timeout_s: float) -> bool:
        if not self._unreleased:
            return True
        if self._lock.acquire(timeout=max(0.0, timeout_s)):
            self._lock.release()  # for any later waiter
            return True
        return not self._unreleased


@dataclass(slots=True)
class PendingCommand:
    message: Message
    seq: int
    wire: bytes
    first_sent_s: float
    deadline_s: float
    attempts: int = 1
    give_up_s: float | None = None  # retried (same seq) until then, however many tries; None: `retries` tries
    ack: m.Ack | None = None
    written_in: int = -1  # the session (count of ground HELLOs) its bytes last left in; -1: never written
    crossed: bool = False  # a retry went out in a later session than an earlier try: the agent may have run it
    mode_mark: int = 0  # the count of mode reports (SAMPLE, HEARTBEAT) when its ACK came
    done: Latch = field(default_factory=Latch)


class PendingCommands:
    """The commands not yet ACKed, by seq; used from the sending threads and the reader thread alike."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._by_seq: dict[int, PendingCommand] = {}

    def add(self, pending: PendingCommand) -> None:
        with self._lock:
            self._by_seq[pending.seq] = pending

    def discard(self, seq: int) -> None:
        with self._lock:
            self._by_seq.pop(seq, None)

    def late(self, now_s: float) -> list[PendingCommand]:
        """Commands whose ACK is overdue."""
        with self._lock:
            return [p for p in self._by_seq.values() if p.ack is None and now_s >= p.deadline_s]

    def acknowledge(self, ack: m.Ack, mode_mark: int = 0) -> PendingCommand | None:
        """The command this ACK answers, now done; None for a stray or repeated ACK."""
        with self._lock:
            pending = self._by_seq.get(ack.cmd_seq)
            if pending is None or pending.message.MSG_ID != ack.cmd_msg_id or pending.ack is not None:
                return None
            pending.ack = ack
            pending.mode_mark = mode_mark
            del self._by_seq[ack.cmd_seq]
        pending.done.set()
        return pending

    def release_all(self) -> None:
        """Wake every waiter without an ACK (the session is closing)."""
        with self._lock:
            waiting, self._by_seq = list(self._by_seq.values()), {}
        for pending in waiting:
            pending.done.set()


# NACKs a retry across a session's start may get because its first try ran (SPEC.md s. 5: "a repeated CMD_START or
# CMD_PAUSE is NOT_ALLOWED_IN_MODE because the first moved the agent").
MAYBE_RAN = frozenset({int(AckResult.NOT_ALLOWED_IN_MODE)})


def result_name(result: int) -> str:
    try:
        return AckResult(result).name
    except ValueError:
        return f"result {result}"


def refusal(name: str, ack: m.Ack) -> CommandError | None:
    """The error for a NACK, naming the result and the agent's reason; None for an ACK that accepts."""
    if ack.result == AckResult.ACCEPTED:
        return None
    why = result_name(ack.result)
    reason = f" ({ack.reason})" if ack.reason else ""
    if ack.result == AckResult.BUSY:
        return AgentBusy(f"{name} refused by the agent: {why}{reason}", ack.result, ack.reason)
    return CommandError(f"{name} refused by the agent: {why}{reason}", ack.result)


def may_have_run(name: str, ack: m.Ack, mode: str) -> CommandMayHaveRun:
    """The report for a NACK of a retry that crossed a session's start: maybe done, and the mode to judge by."""
    return CommandMayHaveRun(f"{name} may have run: the link dropped before its ACK and its retry after the reconnect "
                             f"was answered {result_name(ack.result)}; the agent is {mode}", ack.result, mode)
