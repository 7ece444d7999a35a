"""The viewer choice and the options the view commands share: light, so `dive --help` does not import Rerun."""

from __future__ import annotations

from collections.abc import Callable
from enum import StrEnum
from typing import Annotated, TypeVar

import typer

N = TypeVar("N", int, float, int | None, float | None)


def _number(value: float) -> str:
    """4294967295, not 4.29497e+09; 0.5, not 0.500000."""
    return str(int(value)) if float(value).is_integer() else f"{value:g}"


def ranged(low: float, high: float | None = None) -> Callable[[N], N]:
    """An option's range check, said in one line (typer_help.py) and kept out of `-h`: Typer's own min/max put
    `INTEGER RANGE [0<=x<=4294967295]` in the option column, which split the number across lines at 80 columns."""
    def check(value: N) -> N:
        if value is not None and (value < low or (high is not None and value > high)):
            allowed = f"from {_number(low)} to {_number(high)}" if high is not None else f"{_number(low)} or more"
            raise typer.BadParameter(f"{_number(value)} is out of range: {allowed}")
        return value

    return check


class Viewer(StrEnum):
    SPAWN = "spawn"  # the native viewer, where there is a display
    WEB = "web"  # Rerun's web viewer served on a local port, for headless machines
    NONE = "none"  # no viewer (an .rrd file only, or nothing)


_VIEWERS = ("spawn: the native viewer; web: serve the web viewer on --web-port to your user only (Linux: a "
            "private network); none: no viewer. ")
ViewerOption = Annotated[
    Viewer | None,
    typer.Option("--viewer", metavar="VIEWER", help=_VIEWERS + "Default: spawn where there is a display, else "
                 "web; none when --rrd is given."),
]
RunViewerOption = Annotated[  # `dive run`'s main job needs no viewer: headless, it records only
    Viewer | None,
    typer.Option("--viewer", metavar="VIEWER",  # the choices are in the help: a narrower option column
                 help=_VIEWERS + "Default: spawn where there is a display, else none (--viewer web on "
                 "a headless machine); none when --rrd is given."),
]
WebPortOption = Annotated[int, typer.Option("--web-port", callback=ranged(1, 65535), metavar="PORT",
                                            help="Port of the web viewer (--viewer web).")]
GrpcPortOption = Annotated[int, typer.Option("--grpc-port", callback=ranged(1, 65535), metavar="PORT",
                                             help="Port of the Rerun data stream.")]

FOXGLOVE_DEFAULT_PORT = 8765  # Foxglove's own default for a WebSocket connection
FOXGLOVE_FLAG = "--foxglove"
FoxgloveOption = Annotated[int | None, typer.Option(
    FOXGLOVE_FLAG, callback=ranged(0, 65535), metavar="[PORT]", show_default=False,
    help=f"Serve the agent live to the Foxglove app on ws://127.0.0.1:PORT (default {FOXGLOVE_DEFAULT_PORT}, "
         "0: any free port): every channel, the parameters, and services for the controls. Loopback only, and "
         "only your user's clients get through (the kernel names each client's user; elsewhere than Linux, the "
         "secret path printed).")]


def with_flag_value(args: list[str], flag: str = FOXGLOVE_FLAG, value: str = str(FOXGLOVE_DEFAULT_PORT)) -> list[str]:
    """`--foxglove` given without a port gets the default (Typer has no option with an optional value)."""
    out = []
    for i, word in enumerate(args):
        out.append(word)
        if word == flag and (i + 1 == len(args) or not args[i + 1].isdigit()):
            out.append(value)
    return out
