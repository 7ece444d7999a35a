"""What `dive run` shows while it works: a live bar on a terminal, one line per episode and link event otherwise."""

from __future__ import annotations

import threading
import time
from dataclasses import replace
from types import TracebackType

from rich.console import Console
from rich.progress import BarColumn, MofNCompleteColumn, Progress, SpinnerColumn, TextColumn, TimeElapsedColumn
from rich.table import Column

from groundstation.cli.waiting import PLAIN_EVERY_S, busy_text
from groundstation.run.status import ECHO, RunStatus
from groundstation.safe_output import in_markup, styled
from groundstation.session.events import EventKind, LinkEvent, Received, Sent
from groundstation.session.status_line import status_line

SLOW_START_S = 3.0  # a virtual agent silent this long is loading, or on its first start compiling, its kernels
SLOW_START_NOTE = ("the virtual agent is starting: its first start compiles the simulator (once; about 30 s on an "
                   "idle machine), later starts take seconds")


ACK_HINT = "the alarm flag stays on the status line until acknowledged: the key a here, or dive ack from another pane"


def _run_status_line(s: RunStatus) -> str:
    """The status line (mode, episode, successes, held, target, depth, battery, link, alarm flag): the run counts
    every episode it saw end, so its own count stands in until the agent's EPISODE_END says how many succeeded."""
    agent = replace(s.agent, successes=s.agent.successes if s.agent.successes is not None else s.successes)
    return status_line(agent, s.link, s.link_up, s.alarm_flag)


def describe(s: RunStatus) -> str:
    """The status line in markup for the live bar."""
    line = in_markup(_run_status_line(s))
    line = line.replace("link down", "[red]link down[/]")
    flag = in_markup(s.alarm_flag)
    if flag:  # the last field: an unacknowledged alarm in reverse red, as a console's master caution
        style = "bold white on red" if s.alarm_flag.startswith("ALARM") else "red"
        line = line[: len(line) - len(flag)] + f"[{style}]{flag}[/]"
    return line


def _style(line: str) -> str:
    if line.startswith("ALARM:"):
        return "bold red"
    if line.startswith("cleared:"):
        return "green"
    return "cyan" if line.startswith(ECHO) else "yellow"


class RunDisplay:
    """`show` is the run's progress callback. Not a terminal (a log file, CI): plain lines, each said once."""

    def __init__(self, console: Console, episodes: int, first: str, virtual: bool = False) -> None:
        self.console = console
        # Said only if the agent is still silent after a few seconds: a cached start never shows it.
        self._slow_note = threading.Timer(SLOW_START_S, self._say_slow_start) if virtual else None
        self._connected = False
        self.episodes = episodes
        self.first = first
        self.live = console.is_terminal
        self._progress: Progress | None = None
        self._task: object = None
        self._messages = 0
        self._episodes = 0
        self._hub = ""
        self._mode: int | None = None
        self._alarmed = False
        self._next_busy_line_s = 0.0  # not a terminal: when the next "waiting: BUSY" line may be printed

    def __enter__(self) -> RunDisplay:
        if self.live:
            # The status line wraps rather than being cut: at 80 columns its alarm flag and link came after the "…"
            columns = (SpinnerColumn(), TextColumn("{task.description}", table_column=Column(overflow="fold")),
                       BarColumn(bar_width=20), MofNCompleteColumn(), TimeElapsedColumn())
            self._progress = Progress(*columns, console=self.console, transient=False)
            self._progress.__enter__()
            self._task = self._progress.add_task(in_markup(self.first), total=self.episodes or None)
        else:
            self.console.print(in_markup(self.first), soft_wrap=True)
        if self._slow_note is not None:
            self._slow_note.daemon = True
            self._slow_note.start()
        return self

    # ---- a session listener: while the agent answers BUSY (building its program) the live line says so
    def on_event(self, event: LinkEvent) -> None:
        if event.kind != EventKind.AGENT_BUSY or self._connected:
            return
        if self._slow_note is not None:
            self._slow_note.cancel()  # the agent answers and says what it does: no guess needed
        text = busy_text(event.detail)
        if self._progress is not None:
            self._progress.update(self._task, description=in_markup(text))  # type: ignore[arg-type]
        elif time.monotonic() >= self._next_busy_line_s:
            self._next_busy_line_s = time.monotonic() + PLAIN_EVERY_S
            self.console.print(styled(text, "dim"), soft_wrap=True)

    def on_received(self, received: Received) -> None:
        pass

    def on_sent(self, sent: Sent) -> None:
        pass

    def _say_slow_start(self) -> None:
        if not self._connected:
            printer = self._progress.console if self._progress is not None else self.console
            printer.print(styled(SLOW_START_NOTE, "dim"), soft_wrap=True)

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None,
                 tb: TracebackType | None) -> None:
        if self._slow_note is not None:
            self._slow_note.cancel()
        if self._progress is not None:
            self._progress.__exit__(exc_type, exc, tb)

    def show(self, status: RunStatus) -> None:
        self._connected = self._connected or status.link_up
        printer = self._progress.console if self._progress is not None else self.console
        if status.hub and status.hub != self._hub:
            self._hub = status.hub
            printer.print(styled(f"other tools attach to this run as {status.hub} (dive view, status, mark, "
                                 "surface ...)", "dim"), soft_wrap=True)
        # The session's reader thread appends while this runs: take a count once, so that nothing appended meanwhile
        # is counted as said without being printed (an episode's line went missing that way).
        messages = len(status.messages)
        for line in status.messages[self._messages:messages]:  # agent text among them: data, never markup
            printer.print(styled(line, _style(line)), soft_wrap=True)
            if line.startswith("ALARM:") and self.live:
                printer.bell()
                if not self._alarmed:
                    printer.print(styled(ACK_HINT, "dim"), soft_wrap=True)
            self._alarmed = self._alarmed or line.startswith("ALARM:")
        self._messages = messages
        total = f" of {self.episodes}" if self.episodes else ""
        ends = len(status.ends)
        for i in range(self._episodes, ends):  # above the live status line on a terminal
            episode, outcome, duration_s = status.ends[i]
            ok = sum(end[1] == "success" for end in status.ends[: i + 1])
            chapter = max((number for start, number in status.chapter_starts if start <= i), default=1)
            # After a learner restart the agent numbers episodes from 1 again: the line names the chapter, and the
            # count of the run (what --episodes and the bar count: completed episodes, across restarts).
            done = sum(end[1] in ("success", "failure") for end in status.ends[: i + 1])
            name = f"episode {episode}{total}" if chapter == 1 else \
                f"episode {episode} of chapter {chapter} ({done}{total} in the run)"
            printer.print(f"{name}: {outcome} after {duration_s:.1f} s ({ok} ok so far)",
                          soft_wrap=True, highlight=False)
        self._episodes = ends
        if self._progress is not None:
            self._progress.update(self._task, completed=status.completed,  # type: ignore[arg-type]
                                  description=describe(status))
        elif status.agent.mode is not None and status.agent.mode != self._mode:
            self._mode = status.agent.mode  # not a terminal: the status line when the mode changes
            printer.print(f"status: {_run_status_line(status)}", soft_wrap=True, highlight=False)
