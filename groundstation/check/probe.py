"""The agent's mode as the probe's frames show it: what a check's command met, and waiting for a mode.

A Probe is a LinkProbe (probe_link.py: frames out, every frame in) that follows the mode each live SAMPLE,
HEARTBEAT and EPISODE_START shows, and forgets it where the agent may have left it (an EPISODE_END, the ACK of a
command that moves the agent), so that a check judges a command by the mode the agent was really in.
"""

from __future__ import annotations

import time
from collections.abc import Callable

from groundstation.check.errors import CheckFailed
from groundstation.check.probe_link import (
    ACK_REQUESTED,
    REPLAYED,
    Exchange,
    LinkProbe,
    Timeouts,
    result_name,
)
from groundstation.links import Link
from protocol import AckResult, Message, Mode
from protocol import messages as m
from protocol.cobs import cobs_encode
from protocol.decoder import Frame

__all__ = ["Exchange", "Probe", "Timeouts", "mode_of", "result_name"]

_MODES = {int(x) for x in Mode}
START_AT_REST = "start_at_rest"  # the simulator's parameter (SPEC.md 13), and probe.notes' key for what it holds
PROGRAM_WAIT_S = 900.0  # a virtual agent's build on a cold compile cache: minutes on a loaded machine
BUSY_RETRY_S = 1.0
# Commands whose ACCEPTED may change the mode (SPEC.md 6): the mode shown before their ACK is no longer the present.
_MOVES = {m.StartLearning.MSG_ID, m.Stop.MSG_ID, m.Pause.MSG_ID, m.Surface.MSG_ID, m.Hover.MSG_ID}


def mode_of(frame: Frame) -> Mode | None:
    """The agent's mode a live frame shows (SAMPLE, HEARTBEAT, EPISODE_START); None for other frames."""
    if frame.flags & REPLAYED:
        return None  # a replayed SAMPLE shows a mode of the past
    msg = frame.message
    if isinstance(msg, m.Sample | m.Heartbeat):
        return Mode(msg.mode) if msg.mode in _MODES else None
    if isinstance(msg, m.EpisodeStart):
        return Mode.LEARNING
    return None


class Probe(LinkProbe):
    """A LinkProbe that follows the agent's mode in what it receives."""

    def __init__(self, link: Link, key: bytes | None = None, timeouts: Timeouts | None = None) -> None:
        super().__init__(link, key, timeouts)
        self.mode: Mode | None = None
        self.entered: tuple[Exchange, Mode] | None = None  # a command sent without waiting, and the mode it enters
        self.busy_answers_s: list[float] = []  # how long each BUSY of a starting agent took (runner._await_program)

    def _seen(self, frame: Frame) -> None:
        mode = mode_of(frame)
        if mode is not None:
            self.mode = mode
        elif isinstance(frame.message, m.ParamValue) and frame.message.name == START_AT_REST:
            # Whatever set it (agent.reach, a check putting back every parameter it read before, --param), the
            # value the agent stored: reach must not defer a CMD_START for an episode at rest the agent no longer
            # starts (it recovers first, and a command right behind met RECOVERING, not LEARNING)
            if self.notes.get(START_AT_REST) is not None:
                self.notes[START_AT_REST] = frame.message.value
        elif _ends_present(frame):
            # The mode shown so far is the past: an accepted command that moves the agent (CMD_SURFACE in IDLE
            # shows SURFACING for a step, SPEC.md 6) or an episode that ended. Wait for a frame that shows it.
            self.mode = None

    def _held_sent_alone(self) -> None:
        self.entered = None

    def defer(self, message: Message, enters: Mode) -> None:
        """Hold a command that enters `enters` until the next send, so that both reach the agent in one write: the
        agent handles them back to back, before its next step (on a pty, two writes may be two reads with steps
        between them, long enough for a virtual agent at full speed to leave the mode again)."""
        start = self.end
        inner = self.inner(message.MSG_ID, message.pack(), ACK_REQUESTED)
        self._held += cobs_encode(inner) + b"\x00"
        self.sent_valid += 1
        self.entered = (Exchange(message.MSG_ID, int.from_bytes(inner[2:4], "little"), inner, start), enters)

    def await_program(self, waiting: Callable[[str], None] = lambda _: None) -> str:
        """Until a command is answered other than BUSY (SPEC.md s. 4: a starting agent answers every command BUSY
        until its program runs), `waiting` told each BUSY's reason; each BUSY's answer time is kept for
        link.answer_time. Why the checks cannot go on (still BUSY after PROGRAM_WAIT_S), or ""."""
        started = time.monotonic()
        while True:
            sent_s = time.monotonic()
            ex = self.command(m.ParamGet(index=0, name=""))
            if ex.ack is None or ex.ack.result != AckResult.BUSY:
                return ""  # answered (or not: runner._prepare says so)
            self.busy_answers_s.append(time.monotonic() - sent_s)
            waited_s = time.monotonic() - started
            if waited_s >= PROGRAM_WAIT_S:
                return f"the agent answered every command BUSY for {waited_s:.0f} s ({ex.ack.reason})"
            waiting(ex.ack.reason)
            self.settle(BUSY_RETRY_S)

    def current_mode(self) -> Mode:
        """The mode the agent's newest frames show (waits for one if none has come yet)."""
        self.pump(0.0)
        deadline = time.monotonic() + self.timeouts.heartbeat_s
        while self.mode is None:  # none shown yet, or what was shown is the past (see pump)
            if self.wait(lambda f: mode_of(f) is not None, self.end, max(0.0, deadline - time.monotonic())) is None:
                raise CheckFailed(f"no SAMPLE or HEARTBEAT within {self.timeouts.heartbeat_s:g} s shows the agent's "
                                  "mode")
            self.drain()  # behind a backlog: the newest frames
        return self.mode

    def mode_before(self, ex: Exchange) -> Mode | None:
        """The mode the agent was in when it handled the command: the last mode shown before its ACK.

        A command sent right behind one that enters a mode (`self.entered`, see agent.reach) met that mode if the
        first was ACCEPTED and no frame between the two ACKs shows another; LEARNING only if its EPISODE_START shows
        it.
        """
        entered, self.entered = self.entered, None
        if entered is not None:
            first, mode = entered
            if first.ack is None:
                self.await_ack(first, 0.0)
        for index in range(ex.ack_at - 1, self._first - 1, -1):
            frame = self.frame(index)
            shown = mode_of(frame)
            if shown is not None:
                return shown
            if entered is not None and index == entered[0].ack_at:
                if mode == Mode.LEARNING:
                    # An episode that began says so (its EPISODE_START, right after the ACK): none between the two
                    # ACKs, and the agent met the second command in some other mode (RECOVERING, had it not started
                    # at rest after all): judged as LEARNING, that cell would fail an agent that is right.
                    return None
                return mode if entered[0].result == AckResult.ACCEPTED else None
            if _ends_present(frame):
                return None  # the agent left the mode last shown (an episode ended, a command moved it): unknown
        return None

    def mode_during(self, ex: Exchange) -> Mode | None:
        """The mode the agent was in when it handled a command that does not move it (PARAM_SET, CMD_DUMP...):
        the last mode shown before the ACK, if the first shown after it is the same and no frame between them
        says the agent left it (an EPISODE_END, EPISODE_START, another command that moves it). None when the
        frames around the ACK cannot tell: the caller tries again, it never judges on a guess."""
        if ex.ack is None:
            return None
        before = self.mode_before(ex)
        if before is None:
            return None
        found = self.wait(lambda f: mode_of(f) is not None or _ends_present(f), ex.ack_at + 1,
                          self.timeouts.heartbeat_s)
        if found is None or mode_of(found[1]) != before or isinstance(found[1].message, m.EpisodeStart):
            return None
        return before

    def mode_after(self, ex: Exchange) -> Mode | None:
        """The first mode shown after the command's ACK."""
        found = self.wait(lambda f: mode_of(f) is not None, ex.ack_at + 1, self.timeouts.heartbeat_s)
        return mode_of(found[1]) if found is not None else None

    def wait_mode(self, modes: set[Mode], since: int, timeout_s: float | None = None) -> Mode | None:
        """The first mode in `modes` that a live frame from index `since` on shows; None on timeout."""
        found = self.wait(lambda f: mode_of(f) in modes, since,
                          self.timeouts.mode_s if timeout_s is None else timeout_s)
        return mode_of(found[1]) if found is not None else None


def _ends_present(frame: Frame) -> bool:
    """A live frame after which the mode shown before it may no longer hold: an EPISODE_END (the agent leaves
    LEARNING), or the ACCEPTED ACK of a command that moves the agent."""
    if frame.flags & REPLAYED:
        return False
    msg = frame.message
    if isinstance(msg, m.EpisodeEnd):
        return True
    return isinstance(msg, m.Ack) and msg.result == AckResult.ACCEPTED and msg.cmd_msg_id in _MOVES
