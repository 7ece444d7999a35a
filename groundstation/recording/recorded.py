"""Reading recorded JSON as untrusted input, and telling the agent's boots apart (issue 13 items 1 and 5).

A recording is a file anyone can hand us: a well-formed MCAP may hold a SAMPLE that is `{}`, a list, or not JSON.
Such a message is counted and skipped, never a traceback. Sample indices restart at every agent reboot, so
everything keyed by sample index is kept per boot (the HELLO's boot_id), never spliced across one.
"""

from __future__ import annotations

import json
from typing import Any

from groundstation.mcap_io import RecordedMessage

_NUMBER = (int, float)


def json_object(data: bytes | str) -> dict[str, Any] | None:
    """A recorded body's JSON object; None when it is not JSON or not an object (malformed: the caller counts it)."""
    try:
        body = json.loads(data)
    except (ValueError, UnicodeDecodeError):
        return None
    return body if isinstance(body, dict) else None


def json_fields(msg: RecordedMessage, integers: tuple[str, ...] = (), numbers: tuple[str, ...] = ()
                ) -> dict[str, Any] | None:
    """The message's JSON object if it is one with these integer and number fields; None (malformed) otherwise."""
    body = json_object(msg.data)
    if body is None:
        return None
    for key in integers:
        value = body.get(key)
        if isinstance(value, bool) or not isinstance(value, int):
            return None
    for key in numbers:
        value = body.get(key)
        if isinstance(value, bool) or not (value is None or isinstance(value, _NUMBER)):
            return None  # None: a NaN or infinity the recorder wrote as null
    return body


class Boots:
    """Numbers the agent's boots 1, 2, ... in file order from its HELLOs (a reconnect to the same boot is not one)."""

    def __init__(self) -> None:
        self.current = 1
        self._boot_id: int | None = None

    @property
    def boot_id(self) -> int | None:
        """The agent's boot id of the current boot, once a HELLO or header named it."""
        return self._boot_id

    def hello(self, msg: RecordedMessage) -> bool:
        """Follow a /agent/HELLO; True if it starts a new boot."""
        body = json_fields(msg, integers=("boot_id",))
        if body is None:
            return False
        return self.boot(body["boot_id"])

    def header(self, metadata: dict[str, list[dict[str, str]]]) -> bool:
        """Follow a file's header (its `agent_hello` metadata, the boot the file begins in); True if a new boot.

        A split part after the first holds no HELLO of its own: without this, a reboot inside it would not count.
        """
        boot_id = header_boot_id(metadata)
        return False if boot_id is None else self.boot(boot_id)

    def boot(self, boot_id: int) -> bool:
        new = self._boot_id is not None and boot_id != self._boot_id
        self.current += new
        self._boot_id = boot_id
        return new


def header_boot_id(metadata: dict[str, list[dict[str, str]]]) -> int | None:
    """The boot id of the first `agent_hello` metadata record (the HELLO the file was opened with), if readable."""
    entries = metadata.get("agent_hello") or [{}]
    text = entries[0].get("boot_id", "")
    return int(text) if isinstance(text, str) and text.isdigit() else None
