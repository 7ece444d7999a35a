"""The samples a fit needs, read from MCAP recordings with the mcap library: time, depth, gear angle, command."""

from __future__ import annotations

import json
import struct
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from mcap.exceptions import McapError
from mcap.records import Channel, Message
from mcap.stream_reader import StreamReader
from numpy.typing import NDArray
from zstandard import ZstdError  # the mcap library's decompressor: a damaged chunk raises it

from simulator.errors import SimulatorError

SAMPLE_TOPIC = "/agent/SAMPLE"
HELLO_TOPIC = "/agent/HELLO"
EPISODE_START_TOPIC = "/agent/EPISODE_START"
_TOPICS = (SAMPLE_TOPIC, HELLO_TOPIC, EPISODE_START_TOPIC)
_SAMPLE_FIELDS = ("t_us", "sample", "depth_m", "actuator_deg", "actuator_cmd_deg", "mode")


class FitError(SimulatorError):
    """A recording that cannot be fitted: missing, damaged, too short or without the samples a fit needs."""


@dataclass
class Samples:
    """One row per SAMPLE (deduplicated, in boot then sample order) of one or more recordings."""

    t_s: NDArray[np.float64]  # agent time
    depth_m: NDArray[np.float64]
    alpha_deg: NDArray[np.float64]  # measured gear angle
    cmd_deg: NDArray[np.float64]  # command held until the next sample
    mode: NDArray[np.int64]
    index: NDArray[np.int64]  # the agent's sample index
    run: NDArray[np.int64]  # one number per agent boot: samples of different boots never join
    episode_start: NDArray[np.bool_]  # an episode began at this sample (the paper preset re-places the agent)
    files: list[Path]
    notes: list[str]  # what the reader had to skip (a damaged tail, malformed messages)


def recording_paths(paths: Iterable[str | Path]) -> list[Path]:
    """The .mcap files named; a folder stands for the .mcap files in it, in name order.

    groundstation/recording/tables.py expands folders the same way. Kept twice on purpose: the simulator may not
    import groundstation, and the only packages both may import (protocol, learning) do no file I/O.
    """
    files: list[Path] = []
    for raw in paths:
        path = Path(raw)
        if path.is_dir():
            found = sorted(path.glob("*.mcap"))
            if not found:
                raise FitError(f"{path} holds no .mcap recordings")
            files.extend(found)
        elif not path.is_file():
            raise FitError(f"no such recording: {path}")
        else:
            files.append(path)
    if not files:
        raise FitError("no recording given")
    return files


ReadHook = Callable[[int], None]  # samples read so far
_REPORT_EVERY = 2000  # samples between calls of a ReadHook


def read_samples(paths: Iterable[str | Path], on_read: ReadHook | None = None) -> Samples:
    """Every SAMPLE of the recordings; a damaged or cut-short file gives what was read before the damage."""
    files = recording_paths(paths)
    rows: dict[tuple[int, int], tuple[float, ...]] = {}
    starts: set[tuple[int, int]] = set()
    notes: list[str] = []
    runs: dict[int, int] = {}
    boot = 0  # a split part carries no HELLO of its own: it continues the boot of the part before it
    for path in files:
        boot = _read_file(path, boot, rows, starts, runs, notes, on_read)
    if not rows:
        raise FitError(f"{', '.join(str(f) for f in files)}: no SAMPLE messages to fit")
    keys = sorted(rows, key=lambda k: (k[0], rows[k][1]))
    table = np.array([rows[k] for k in keys], dtype=np.float64)
    return Samples(
        t_s=table[:, 0] * 1e-6, depth_m=table[:, 2], alpha_deg=table[:, 3], cmd_deg=table[:, 4],
        mode=table[:, 5].astype(np.int64), index=table[:, 1].astype(np.int64),
        run=np.array([k[0] for k in keys], dtype=np.int64),
        episode_start=np.array([k in starts for k in keys], dtype=np.bool_), files=files, notes=notes,
    )


def _read_file(path: Path, boot: int, rows: dict[tuple[int, int], tuple[float, ...]],
               starts: set[tuple[int, int]], runs: dict[int, int], notes: list[str],
               on_read: ReadHook | None) -> int:
    """Adds the file's samples to rows (keyed by run and sample index, so a backfilled sample counts once);
    returns the boot id the file ends in."""
    channels: dict[int, Channel] = {}
    malformed = 0
    records = 0
    try:
        with open(path, "rb") as stream:
            for record in StreamReader(stream, skip_magic=False).records:
                records += 1
                if isinstance(record, Channel):
                    channels[record.id] = record
                    continue
                if not isinstance(record, Message):
                    continue
                channel = channels.get(record.channel_id)
                if channel is None or channel.topic not in _TOPICS or channel.message_encoding != "json":
                    continue
                try:
                    body = json.loads(record.data)
                except ValueError:
                    malformed += 1
                    continue
                if not isinstance(body, dict):
                    malformed += 1
                    continue
                if channel.topic == HELLO_TOPIC:
                    boot_id = body.get("boot_id")
                    boot = boot_id if isinstance(boot_id, int) else boot
                    continue
                run = runs.setdefault(boot, len(runs))
                if channel.topic == EPISODE_START_TOPIC:
                    if isinstance(body.get("sample"), int):
                        starts.add((run, body["sample"]))
                    continue
                values = [body.get(name) for name in _SAMPLE_FIELDS]
                if not all(isinstance(v, int | float) and not isinstance(v, bool) for v in values):
                    malformed += 1
                    continue
                rows[(run, int(body["sample"]))] = tuple(float(v) for v in values)  # type: ignore[arg-type]
                if on_read is not None and len(rows) % _REPORT_EVERY == 0:
                    on_read(len(rows))
    except OSError as e:
        raise FitError(f"cannot read {path}: {e.strerror or e}") from e
    except (McapError, ValueError, EOFError, KeyError, IndexError, struct.error, ZstdError) as e:
        if records <= 1:  # not one record past the header: an empty, random or magic-only file (issue 38 N10)
            raise FitError(f"{path}: not an MCAP recording (empty, or no record after its start)") from None
        # A cut-short recording (a crash) or a damaged chunk: what came before it is still good data.
        notes.append(f"{path}: read up to damage ({type(e).__name__}: {e}); the samples before it are used")
    if malformed:
        notes.append(f"{path}: {malformed} malformed messages left out")
    return boot
