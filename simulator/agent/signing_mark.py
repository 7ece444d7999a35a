"""The virtual agent's non-volatile signing mark (SPEC.md section 12): a small state file instead of an EEPROM."""

from __future__ import annotations

import os
import sys
import tempfile
from pathlib import Path

from simulator.errors import SimulatorError


class MarkFile:
    """One decimal number in a file: the mark below which signed timestamps are refused after a restart.

    Written atomically (a temporary file renamed over it), so a crash mid-write leaves the previous mark.
    """

    def __init__(self, path: Path) -> None:
        self.path = path
        self._warned = False

    def read(self) -> int:
        """The stored mark, -1 if there is none yet; SimulatorError if the file holds something else."""
        try:
            text = self.path.read_text(encoding="ascii").strip()
        except FileNotFoundError:
            return -1
        except (OSError, UnicodeDecodeError) as e:
            raise SimulatorError(f"cannot read the signing state {self.path}: {e}") from e
        if not text.isdigit():
            raise SimulatorError(f"signing state {self.path} does not hold a timestamp; delete it to start afresh")
        return int(text)

    def write(self, mark: int) -> None:
        """Store a new mark. A failure (disk full, read-only) is reported once on stderr; the agent keeps running."""
        try:
            self.path.parent.mkdir(parents=True, exist_ok=True)
            fd, tmp = tempfile.mkstemp(dir=self.path.parent, prefix=self.path.name, suffix=".tmp")
            with os.fdopen(fd, "w", encoding="ascii") as out:
                out.write(f"{mark}\n")
            os.replace(tmp, self.path)
        except OSError as e:
            if not self._warned:
                self._warned = True
                print(f"warning: cannot store the signing state {self.path}: {e.strerror or e}", file=sys.stderr)


def mark_path(key_file: Path, state_dir: Path | None) -> Path:
    """Where the mark of an agent with this key lives: in state_dir, else next to the key file."""
    return (state_dir if state_dir is not None else key_file.parent) / f"{key_file.name}.mark"
