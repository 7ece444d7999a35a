"""The ground station's exception base and its specific errors (the CLI maps each to one line)."""

from __future__ import annotations


class GroundStationError(Exception):
    """Base of every error the ground station raises on purpose."""


class LinkError(GroundStationError, ConnectionError):
    """The link could not be opened, or failed while in use."""


class LinkTimeout(LinkError, TimeoutError):
    """The peer did not answer in time (no HELLO, link timeout)."""


class UnknownSchemeError(LinkError, ValueError):
    """A link URL whose scheme no backend handles."""


class BadUrlError(UnknownSchemeError):
    """A link URL that cannot be read (a port outside 0-65535, a bracket not closed): bad usage, exit 2."""


class IncompatibleAgentError(LinkError):
    """The agent speaks another protocol version or another message table."""


class CommandError(GroundStationError):
    """A command was refused (NACK) by the agent; `result` is the ACK's result code (None: no ACK came)."""

    def __init__(self, message: str, result: int | None = None) -> None:
        super().__init__(message)
        self.result = result


class AgentBusy(CommandError):
    """The agent answered BUSY (SPEC.md s. 5: try again later), as a virtual agent does while its program builds;
    `reason` is its ACK's reason (how far it got)."""

    def __init__(self, message: str, result: int | None = None, reason: str = "") -> None:
        super().__init__(message, result)
        self.reason = reason


class CommandTimeout(CommandError, TimeoutError):
    """No ACK after every retry."""


class CommandMayHaveRun(CommandError):
    """A retry that crossed a session's start was refused in a way that shows the first try may have run (SPEC.md
    s. 5): not a plain refusal. `mode` is the agent's mode from its next SAMPLE or HEARTBEAT after the NACK."""

    def __init__(self, message: str, result: int, mode: str) -> None:
        super().__init__(message, result)
        self.mode = mode


class ParameterError(GroundStationError, ValueError):
    """An unknown parameter name or a value outside its range."""


class RecordingError(GroundStationError, OSError):
    """A recording that cannot be written, read or recovered."""


class RecordingExistsError(RecordingError, FileExistsError):
    """A recording would replace an existing file (never done: a new name is chosen or the user gives one)."""


class RecordingTooLargeError(RecordingError):
    """A recording whose records claim more data than its size on disk can hold (a damaged or hostile file)."""


class AgentChangedError(LinkError):
    """After a reconnect another agent (another node id) answered at the same address."""


class ListenerError(GroundStationError):
    """A listener of the session (the recorder, the live view) raised: the run stops rather than go on without it."""


class LinkTakenError(LinkError):
    """The agent told this ground that another ground's connection replaced it (SPEC.md s. 3)."""


class HubDroppedError(LinkError):
    """The run's hub dropped this tool: it fell too far behind reading what the hub fans out (run/hub_outbox.py)."""
