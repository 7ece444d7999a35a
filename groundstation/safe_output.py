"""Text from the agent or a file name is data: never Rich markup, never terminal control (issue 13 item 8).

Every string `dive` prints may hold bytes it did not write: a HELLO name, a NACK reason, a parameter name, a
TEXT line, a file path. Two things can go wrong: Rich reads `[/]` or `[bold]` in it as markup (and raises on a
closing tag without an opening one), and an ESC, CSI or bidi-override character reaches the terminal raw. So
every console of the command line is a `SafeConsole`: markup and emoji codes off, every printed string passed
through `printable()` first. Our own styling goes in `style=` or `styled()`, never inside the text.
"""

from __future__ import annotations

import unicodedata
from typing import Any

from rich.console import Console
from rich.markup import escape
from rich.text import Text

# Format characters that reorder or hide text on a terminal (bidi overrides and isolates, zero-width marks).
_HIDDEN = {0x200B, 0x200E, 0x200F, 0x202A, 0x202B, 0x202C, 0x202D, 0x202E, 0x2066, 0x2067, 0x2068, 0x2069, 0xFEFF}


def _escape(char: str) -> str:
    code = ord(char)
    return f"\\x{code:02x}" if code < 0x100 else f"\\u{code:04x}"


def printable(text: object, keep_newlines: bool = True) -> str:
    """`text` with every control character (C0, DEL, C1, bidi overrides) shown as an escape like `\\x1b`.

    Newlines (and tabs) stay when `keep_newlines`: a multi-line report is ours; a field from the agent
    should be passed with keep_newlines=False, so it cannot start a line that looks like ours.
    """
    text = str(text)
    if text.isprintable():
        return text
    kept = "\n\t" if keep_newlines else ""
    return "".join(
        c if c in kept or not (unicodedata.category(c) == "Cc" or ord(c) in _HIDDEN) else _escape(c) for c in text)


def one_line(text: object) -> str:
    """One field of agent or file text on one line: control characters and newlines escaped."""
    return printable(text, keep_newlines=False)


def in_markup(text: object) -> str:
    """Text to put inside a string Rich parses as markup (a progress description): escaped, one line."""
    return escape(one_line(text))


def styled(text: object, style: str) -> Text:
    """Printable text in a style (never parsed as markup)."""
    return Text(printable(text), style=style)


class SafeConsole(Console):
    """A Rich console that prints strings as data: no markup, no emoji codes, control characters escaped."""

    def __init__(self, **kwargs: Any) -> None:
        kwargs.setdefault("markup", False)
        kwargs.setdefault("emoji", False)
        kwargs.setdefault("highlight", False)
        super().__init__(**kwargs)

    def print(self, *objects: Any, **kwargs: Any) -> None:  # type: ignore[override]
        kwargs["markup"] = False
        kwargs["emoji"] = False
        if all(isinstance(o, str | Text) for o in objects):
            # A line of text is never broken by us: a path or a figure in it must survive whole for the user to
            # copy (the terminal may still fold it on screen). Tables and panels keep Rich's layout.
            kwargs.setdefault("soft_wrap", True)
        super().print(*(printable(o) if isinstance(o, str) else o for o in objects), **kwargs)
