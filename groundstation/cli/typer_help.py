"""Typer's rich help and error boxes, loaded without the two renderers it imports and `dive` never uses.

typer.rich_utils imports rich.markdown (the markdown-it parser, ~30 % of `dive --help`'s imports) for the
"markdown" help mode and rich.traceback (with attrs and pygments) for pretty exceptions; `dive` uses the "rich"
mode and turns pretty exceptions off. Both names are bound to stand-ins that import the real class on first
use, so nothing breaks if a later Typer uses them after all. Typer is pinned below 0.21 (pyproject.toml); a test
checks that `dive --help` still imports neither and prints the same help.
"""

from __future__ import annotations

import importlib
import re
import sys
import types
from typing import Any

_DEFERRED = {"rich.markdown": "Markdown", "rich.traceback": "Traceback"}


class _OnFirstUse(type):
    """A class standing for `module.name`: calling it or asking it for an attribute imports and forwards to the
    real one. Dunder names are not forwarded: `typing` probes them while rich_utils's annotations are built."""

    _module: str
    _name: str

    def _real(cls) -> Any:
        return getattr(importlib.import_module(cls._module), cls._name)

    def __call__(cls, *args: Any, **kwargs: Any) -> Any:
        return cls._real()(*args, **kwargs)

    def __getattr__(cls, attribute: str) -> Any:
        if attribute.startswith("__"):
            raise AttributeError(attribute)
        return getattr(cls._real(), attribute)


def _one_line_usage_error(format_error: Any) -> Any:
    """Typer's error printer, but every usage error (`--episodes -3`, `--web-port 70000`, an unknown command or
    option, a missing argument) is the one line the README promises (exit 2, as before), not a usage line, a hint
    and a 5-line box: the message names what was wrong, and the line says where the options are listed."""
    import click
    from rich.text import Text

    from groundstation.cli.common import command_path, err

    def format_usage_error(error: click.ClickException) -> None:
        if not isinstance(error, click.UsageError):
            format_error(error)
            return
        # Typer's group adds its "Did you mean" to click's, which already has one: say each sentence once.
        sentences = re.split(r"(?<=[.?!])\s+", error.format_message().strip())
        message = " ".join(dict.fromkeys(x for x in sentences if x))
        context = getattr(error, "ctx", None)
        listed = "the commands" if isinstance(getattr(context, "command", None), click.Group) else "the options"
        where = f" ({command_path(context)} -h lists {listed})" if context is not None else ""
        err.print(Text.assemble(("dive:", "bold red"), f" {message[:1].lower()}{message[1:].rstrip('.')}{where}"),
                  soft_wrap=True)

    return format_usage_error


def load_typer_help() -> None:
    """Import typer.rich_utils with the stand-ins in place; the real modules stay importable as before."""
    if "typer.rich_utils" in sys.modules:
        return
    stand_ins: dict[str, types.ModuleType] = {}
    for module, name in _DEFERRED.items():
        if module not in sys.modules:
            stand_in = types.ModuleType(module)
            setattr(stand_in, name, _OnFirstUse(name, (), {"_module": module, "_name": name}))
            stand_ins[module] = stand_in
    sys.modules.update(stand_ins)
    try:
        import typer.rich_utils

        typer.rich_utils.rich_format_error = _one_line_usage_error(typer.rich_utils.rich_format_error)
    finally:
        for module, stand_in in stand_ins.items():
            if sys.modules.get(module) is stand_in:
                del sys.modules[module]
