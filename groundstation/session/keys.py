"""Signing keys (SPEC.md section 12): `dive keygen`, and the key for a session from --key-file or $DIVE_KEY_FILE."""

from __future__ import annotations

import os
from pathlib import Path
from typing import Annotated

import typer

from groundstation.errors import GroundStationError
from groundstation.safe_output import one_line

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
    import secrets  # here, with the protocol: `dive --help` needs neither

    from protocol.signing import KEY_SIZE, format_key

    with os.fdopen(fd, "w", encoding="ascii") as f:
        os.fchmod(f.fileno(), 0o600)  # O_TRUNC on an existing file keeps its old mode
        f.write(format_key(secrets.token_bytes(KEY_SIZE)))
    return path


def read_key_file(path: Path) -> bytes:
    """The key in `path`; a file that others (group or world) may read is refused: the key is no secret then."""
    from protocol import SigningError
    from protocol.signing import parse_key

    try:
        mode = path.stat().st_mode
        if mode & 0o077:
            raise KeyFileError(f"key file {one_line(path)} is readable by others (mode {mode & 0o777:03o}); "
                               f"run: chmod 600 {one_line(path)}")
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


KeyFileOption = Annotated[Path | None, typer.Option(
    "--key-file", help=f"sign commands with the key in this file (default: ${KEY_FILE_ENV})", show_default=False)]


def keygen(
    out: Annotated[Path, typer.Option("--out", help="key file to write (64 hex digits, mode 0600)")] = DEFAULT_KEY_FILE,
    force: Annotated[bool, typer.Option(help="replace an existing key file")] = False,
) -> None:
    """Write a new random signing key; give it to the agent (dive sim --key-file) and to dive (--key-file)."""
    try:
        path = write_key_file(out, force)
    except KeyFileError as e:
        typer.echo(f"dive: {one_line(e)}", err=True)
        raise typer.Exit(1) from None
    typer.echo(one_line(path))
    shown = one_line(path)
    typer.echo(f"agent: dive sim --key-file {shown}; ground: export {KEY_FILE_ENV}={shown}", err=True)
