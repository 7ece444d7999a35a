"""The viewer choice and the options the view commands share: light, so `dive --help` does not import Rerun."""

from __future__ import annotations

from enum import StrEnum
from typing import Annotated

import typer


class Viewer(StrEnum):
    SPAWN = "spawn"  # the native viewer, where there is a display
    WEB = "web"  # Rerun's web viewer served on a local port, for headless machines
    NONE = "none"  # no viewer (an .rrd file only, or nothing)


_VIEWERS = "spawn: the native viewer; web: serve the web viewer on --web-port; none: no viewer. "
ViewerOption = Annotated[
    Viewer | None,
    typer.Option("--viewer", help=_VIEWERS + "Default: spawn where there is a display, else web; none when --rrd "
                 "is given."),
]
RunViewerOption = Annotated[  # `dive run`'s main job needs no viewer: headless, it records only
    Viewer | None,
    typer.Option("--viewer", help=_VIEWERS + "Default: spawn where there is a display, else none (--viewer web on "
                 "a headless machine); none when --rrd is given."),
]
WebPortOption = Annotated[int, typer.Option("--web-port", min=1, max=65535,
                                            help="Port of the web viewer (--viewer web).")]
GrpcPortOption = Annotated[int, typer.Option("--grpc-port", min=1, max=65535, help="Port of the Rerun data stream.")]
