"""The compiled fast path (protocol/fast_frames.py, numba) loaded in the background, never waited for.

Importing numba and loading the cached kernels takes about a second on an idle machine and several on a
loaded one: a ground station must not spend that before its first HELLO. The first call starts a daemon
thread that imports fast_frames and runs each kernel once; until it is done (or where numba is not
installed) callers get None and take the stdlib codec, which gives the same bytes.
"""

from __future__ import annotations

import threading
from types import ModuleType

_module: ModuleType | None = None
_started = False
_lock = threading.Lock()
_done = threading.Event()


def fast_frames() -> ModuleType | None:
    """protocol.fast_frames once it is loaded and warm; None before (the load starts here) or without numba."""
    if _module is None and not _started:
        _start()
    return _module


def wait(timeout_s: float | None = None) -> bool:
    """Block until the load has finished (benchmarks, tests); True if the compiled path is there."""
    if not _started:
        _start()
    _done.wait(timeout_s)
    return _module is not None


def _start() -> None:
    global _started
    with _lock:
        if _started:
            return
        _started = True
    threading.Thread(target=_load, name="protocol-compiled-load", daemon=True).start()


def _load() -> None:
    global _module
    try:
        from protocol import fast_frames

        fast_frames.warm_up()
        _module = fast_frames
    except ImportError:
        pass  # no numba: the stdlib codec does the work
    finally:
        _done.set()
