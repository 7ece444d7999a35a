"""Signing keys (SPEC.md section 12): `dive keygen`, and the key for a session from --key-file or $DIVE_KEY_FILE."""

from __future__ import annotations

import os
import secrets
from pathlib import Path
from typing import Annotated

import typer

from groundstation.errors import GroundStationError

KEY_FILE_ENV = "DIVE_KEY_FILE"
DEFAULT_KEY_FILE = Path("dive.key")


class KeyFileError(GroundStationError, ValueError):
    """A key file that cannot be read, holds no valid key, or would overwrite one."""


def write_key_file(path: Path, force: bool = False) -> Path:
    """A new random key in `path`, readable by its owner only (0600 from the start, never world-readable)."""
    flags = os.O_WRONLY | os.O_CREAT | (os.O_TRUNC if force else os.O_EXCL)
    try:
        fd = os.open(path, flags, 0o600)
    except FileExistsError as e:
        raise KeyFileError(f"{path} exists; keep it, or pass --force to replace it (the agent needs the new key too)"
                           ) from e
    except OSError as e:
        raise KeyFileError(f"cannot write key file {path}: {e.strerror or e}") from e
    from protocol.signing import KEY_SIZE, format_key  # here: `dive --help` does not load the protocol

    with os.fdopen(fd, "w", encoding="ascii") as f:
        os.fchmod(f.fileno(), 0o600)  # O_TRUNC on an existing file keeps its old mode
        f.write(format_key(secrets.token_bytes(KEY_SIZE)))
    return path


def read_key_file(path: Path) -> bytes:
    from protocol import SigningError
    from protocol.signing import parse_key

    try:
        return parse_key(path.read_text(encoding="ascii"))
    except (OSError, UnicodeDecodeError) as e:
        raise KeyFileError(f"cannot read key file {path}: {getattr(e, 'strerror', None) or e}") from e
    except SigningError as e:
        raise KeyFileError(f"{path}: {e}") from e


def resolve_key(key_file: Path | None = None) -> bytes | None:
    """The session's signing key: --key-file, else $DIVE_KEY_FILE, else None (frames go unsigned)."""
    if key_file is None:
        env = os.environ.get(KEY_FILE_ENV)
        key_file = Path(env) if env else None
    return read_key_file(key_file) if key_file is not None else None


def keygen(
    out: Annotated[Path, typer.Option("--out", help="key file to write (64 hex digits, mode 0600)")] = DEFAULT_KEY_FILE,
    force: Annotated[bool, typer.Option(help="replace an existing key file")] = False,
) -> None:
    """Write a new random signing key; give it to the agent (serve --key-file) and to dive (--key-file)."""
    try:
        path = write_key_file(out, force)
    except KeyFileError as e:
        typer.echo(f"dive: {e}", err=True)
        raise typer.Exit(1) from None
    typer.echo(str(path))
    typer.echo(f"agent: python -m simulator serve --key-file {path}; ground: export {KEY_FILE_ENV}={path}", err=True)
