"""No command destroys a recording (issue 13 item 2): outputs go to a temporary file renamed into place, never onto
their own input or onto another recording, and a new recording never takes an existing file's name.

The live recording is the exception to "temporary file, then rename": a kill -9 would then lose all of it. It is
written in place, flushed every second, under a name created exclusively (O_EXCL), so it can never replace or be
replaced by another file (docs/reliability.md, "Files").
"""

from __future__ import annotations

import os
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from groundstation.errors import RecordingError
from groundstation.safe_output import one_line

MCAP_MAGIC = b"\x89MCAP0\r\n"


def is_recording(path: Path) -> bool:
    """True if `path` is an existing file that starts like an MCAP recording."""
    try:
        with path.open("rb") as f:
            return f.read(len(MCAP_MAGIC)) == MCAP_MAGIC
    except OSError:
        return False


def _same_file(a: Path, b: Path) -> bool:
    try:
        return a.exists() and b.exists() and os.path.samefile(a, b)
    except OSError:
        return a.resolve() == b.resolve()


def check_output(target: Path, source: Path | None = None) -> None:
    """Refuse an output that is its own input, an existing recording, a folder or in no folder, saying why."""
    if target.is_dir():
        raise RecordingError(f"{one_line(target)} is a folder: give a file name")
    if not target.parent.is_dir():
        raise RecordingError(f"there is no folder {one_line(target.parent)} to write {one_line(target.name)} into")
    if source is not None and (_same_file(target, source) or target.resolve() == source.resolve()):
        raise RecordingError(f"--out {one_line(target)} is the input file; writing it would destroy the recording: "
                             "give another name")
    if is_recording(target):
        raise RecordingError(f"{one_line(target)} is an existing recording; it is never overwritten: give another name")


def unused_name(path: Path) -> Path:
    """`path`, or `name-2.ext`, `name-3.ext`, ... the first that does not exist yet."""
    candidate, number = path, 1
    while candidate.exists():
        number += 1
        candidate = path.with_name(f"{path.stem}-{number}{path.suffix}")
    return candidate


@contextmanager
def replaced_atomically(target: Path, source: Path | None = None) -> Iterator[Path]:
    """A temporary path beside `target`; renamed onto `target` when the block succeeds, removed when it fails.

    So a failed or interrupted export never leaves a half-written file under the name asked for, and never
    touches `source` (checked by check_output first).
    """
    check_output(target, source)
    # the same suffix: numpy.savez adds ".npz" to a name without it
    temporary = target.with_name(f".{target.stem}.{os.getpid()}.tmp{target.suffix}")
    temporary.unlink(missing_ok=True)  # left by an earlier process with our pid that was killed
    try:
        yield temporary
        os.replace(temporary, target)
    finally:
        temporary.unlink(missing_ok=True)


def create_exclusive(path: Path) -> int:
    """Create `path` for writing, failing with FileExistsError if anything has that name (O_EXCL)."""
    return os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o644)
