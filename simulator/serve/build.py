"""Builds the on-board program on a thread of its own, counting the kernels numba compiles, so the link is answered
meanwhile (serve/starting.py): on a cold compile cache the build takes minutes on a loaded machine."""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from typing import Any, Generic, TypeVar

BUILD_DELAY_ENV = "DIVE_SIM_BUILD_DELAY_S"  # for tests: the build waits this long first, as a cold compile would

T = TypeVar("T")


class BuildProgress:
    """What the build has done so far: read from the serving thread while the build thread writes it."""

    def __init__(self, clock_s: Callable[[], float] = time.monotonic) -> None:
        self._clock_s = clock_s
        self.started_s = clock_s()
        self.compiled = 0  # kernels numba compiled (a kernel loaded from the cache is not counted)
        self.compiling = ""  # the one it compiles now, "" between kernels

    def elapsed_s(self) -> float:
        return self._clock_s() - self.started_s

    def describe(self) -> str:
        """One line for a TEXT or a BUSY's reason: what the agent is doing, how far it got, for how long."""
        now = f", now {self.compiling}" if self.compiling else ""
        return f"building its program: {self.compiled} kernels compiled{now} ({self.elapsed_s():.0f} s)"


class ProgramBuild(Generic[T]):
    """`make()` run on a daemon thread, its numba compiles counted into `progress`; `result()` once it is done."""

    def __init__(self, make: Callable[[], T], delay_s: float = 0.0) -> None:
        self.progress = BuildProgress()
        self._make = make
        self._delay_s = delay_s
        self._result: T | None = None
        self._error: BaseException | None = None
        self._thread = threading.Thread(target=self._run, name="program-build", daemon=True)

    def start(self) -> None:
        self._thread.start()

    @property
    def done(self) -> bool:
        return not self._thread.is_alive()

    def result(self) -> T:
        """The program (after `done`); the build's own exception if it failed."""
        self._thread.join()
        if self._error is not None:
            raise self._error
        assert self._result is not None
        return self._result

    def _run(self) -> None:
        listener = _compile_listener(self.progress)
        try:
            self._result = self._make()
            if self._delay_s > 0:
                # The test hook (BUILD_DELAY_ENV): a slow build without a cold cache, slow after the program's link
                # exists, as a cold compile is (the link must take the connection's state at the hand-over)
                time.sleep(self._delay_s)
        except BaseException as e:  # noqa: BLE001 - handed to the serving thread, which reports it
            self._error = e
        finally:
            if listener is not None:
                from numba.core import event

                event.unregister("numba:compile", listener)


def _compile_listener(progress: BuildProgress) -> Any:
    """A numba event listener that counts compiles into `progress` (registered here); None without numba."""
    try:
        from numba.core import event
    except ImportError:
        return None

    class Counter(event.Listener):  # type: ignore[misc]  # numba is untyped
        def __init__(self) -> None:
            self.open: list[str] = []  # a kernel's callees compile inside its own compile

        def on_start(self, ev: event.Event) -> None:
            dispatcher = ev.data.get("dispatcher") if isinstance(ev.data, dict) else None
            self.open.append(getattr(getattr(dispatcher, "py_func", None), "__name__", "a kernel"))
            progress.compiling = self.open[-1]

        def on_end(self, ev: event.Event) -> None:
            if self.open:
                self.open.pop()
            progress.compiled += 1
            progress.compiling = self.open[-1] if self.open else ""

    listener = Counter()
    event.register("numba:compile", listener)
    return listener
