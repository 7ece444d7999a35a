"""The viewer choice and the options the view commands share: light, so `dive --help` does not import Rerun."""

from __future__ import annotations

from enum import StrEnum
from typing import Annotated

import typer


class Viewer(StrEnum):
    SPAWN = "spawn"  # the native viewer, where there is a display
    WEB = "web"  # Rerun's web viewer served on a local port, for headless machines
    NONE = "none"  # no viewer (an .rrd file only, or nothing)


ViewerOption = Annotated[
    Viewer | None,
    typer.Option("--viewer", help="spawn: native viewer; web: serve the web viewer on --web-port; none. "
                 "Default: spawn with a display, else web (none when only --rrd is given)."),
]
WebPortOption = Annotated[int, typer.Option("--web-port", min=1, max=65535,
                                            help="Port of the web viewer (--viewer web).")]
GrpcPortOption = Annotated[int, typer.Option("--grpc-port", min=1, max=65535, help="Port of the Rerun data stream.")]
