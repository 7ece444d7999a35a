"""Parameter files: TOML `name = value` lines (read with tomllib), the one format of `dive run`, `sim` and `params`.

A top-level table of numbers and booleans; a `[params]` table is read the same (the simulator's files may
hold other tables beside it). `dive params save` writes what `load` and `dive run --params` read back.
"""

from __future__ import annotations

import json
import math
import struct
import tomllib
from pathlib import Path

from groundstation.errors import ParameterError
from groundstation.session.params import ParamTable

PLANT_TABLE = "plant"  # a plant file's figures (`dive fit`): the simulator's, not the agent's

MAX_FILE_BYTES = 1024 * 1024  # a parameter file is a few KiB; a plant file (`dive fit`) too


def read_params(path: Path) -> dict[str, str]:
    """name -> value text (booleans as true/false), for Session.set_param."""
    data = _read_table(path)
    table = data.get("params")
    if isinstance(table, dict):
        data = table
    values = {}
    for name, value in data.items():
        if isinstance(value, bool):
            values[str(name)] = "true" if value else "false"
        elif isinstance(value, int | float):
            values[str(name)] = repr(value)
        elif isinstance(value, dict):
            continue  # another table (the simulator's plant settings, ...)
        else:
            raise ParameterError(f"{path}: {name} = {value!r} is not a number or true/false")
    return values


def has_plant_table(path: Path) -> bool:
    """Whether the file holds a [plant] table, which only a simulator can take (`dive run` hands it over)."""
    return isinstance(_read_table(path).get(PLANT_TABLE), dict)


def _read_table(path: Path) -> dict[str, object]:
    try:
        with path.open("rb") as f:
            raw = f.read(MAX_FILE_BYTES + 1)  # bounded: `--params /dev/zero` once grew to 20 GB (issue 38 N6)
    except OSError as e:
        raise ParameterError(f"cannot read parameter file {path}: {e.strerror or e}") from e
    if len(raw) > MAX_FILE_BYTES:
        raise ParameterError(f"{path}: larger than {MAX_FILE_BYTES // 1024} KiB: not a parameter file")
    try:
        text = raw.decode()
    except UnicodeDecodeError:
        raise ParameterError(f"{path}: not UTF-8 text: not a parameter file") from None
    if text.lstrip().startswith("{"):  # a JSON object (older files): still read
        try:
            data = json.loads(text)
        except (ValueError, RecursionError) as e:
            raise ParameterError(f"{path}: not valid JSON ({type(e).__name__})") from None
    else:
        try:
            data = tomllib.loads(text)
        except tomllib.TOMLDecodeError as e:
            raise ParameterError(f"{path}: not valid TOML ({e}); write `name = value` lines") from e
        except RecursionError:
            raise ParameterError(f"{path}: nested too deeply to be a parameter file") from None
    if not isinstance(data, dict):
        raise ParameterError(f"{path}: expected `name = value` lines")
    return data


def format_params(table: ParamTable) -> str:
    """The table as TOML, one `name = value` line each, with its range as a comment."""
    lines = ["# agent parameters, written by `dive params save`; read by `dive params load` and `dive run --params`"]
    for p in table:
        if p.display_value in ("true", "false"):
            value = p.display_value
        elif p.display_value.lstrip("-").isdigit():
            value = p.display_value
        else:
            value = _shortest_f32(p.value) if math.isfinite(p.value) else "nan"
        lines.append(f"{p.name} = {value}  # [{p.minimum:g}, {p.maximum:g}]")
    return "\n".join(lines) + "\n"


def _shortest_f32(value: float) -> str:
    """The shortest decimal that is the same f32 (0.4, not 0.4000000059604645: the agent stores f32)."""
    stored = struct.pack("<f", value)
    for digits in range(1, 18):
        text = f"{value:.{digits}g}"
        if struct.pack("<f", float(text)) == stored:
            return text if any(c in text for c in ".en") else text + ".0"
    return repr(value)


def write_params(path: Path, table: ParamTable) -> None:
    try:
        path.write_text(format_params(table))
    except OSError as e:
        raise ParameterError(f"cannot write {path}: {e.strerror or e}") from e
