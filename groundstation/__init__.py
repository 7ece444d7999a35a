"""The host application: links, session, recorder, live view, replay and the `dive` CLI.

`from groundstation import open_recording` reads recordings as numpy tables (groundstation/recording/tables.py).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from groundstation.recording.tables import Recording, open_recording

__all__ = ["Recording", "open_recording"]


def __getattr__(name: str) -> Any:
    # Imported on first use: `dive --help` must not pay for the MCAP reader.
    if name in __all__:
        from groundstation.recording import tables as recording

        return getattr(recording, name)
    raise AttributeError(f"module 'groundstation' has no attribute {name!r}")
