"""The agent's parameter table: fetched at connect (PARAM_LIST), cached on disk by definitions hash and agent id."""

from __future__ import annotations

import json
import os
from dataclasses import asdict, dataclass
from pathlib import Path

from groundstation.errors import ParameterError
from protocol import ParamType
from protocol.messages import ParamValue
from protocol.parameters import f32


@dataclass(frozen=True, slots=True)
class Parameter:
    index: int
    name: str
    param_type: ParamType
    value: float
    minimum: float
    maximum: float

    @classmethod
    def from_message(cls, m: ParamValue) -> Parameter:
        try:
            kind = ParamType(m.param_type)
        except ValueError:
            kind = ParamType.F32
        return cls(m.index, m.name, kind, m.value, m.minimum, m.maximum)

    @property
    def display_value(self) -> str:
        if self.param_type == ParamType.BOOL:
            return "true" if self.value else "false"
        if self.param_type in (ParamType.U8, ParamType.I32, ParamType.U32):
            return str(int(self.value))
        return f"{self.value:g}"


_WHOLE = (ParamType.U8, ParamType.I32, ParamType.U32, ParamType.BOOL)  # the agent refuses 3.7 for these


def parse_value(param: Parameter, text: str) -> float:
    """A user's value for a parameter, checked against its type and range."""
    lowered = text.strip().lower()
    if param.param_type == ParamType.BOOL and lowered in ("true", "false", "on", "off", "yes", "no"):
        return 1.0 if lowered in ("true", "on", "yes") else 0.0
    try:
        value = float(lowered)
    except ValueError:
        raise ParameterError(f"{param.name}: {text!r} is not a number") from None
    stored = f32(value) if param.param_type == ParamType.F32 else value  # the agent checks the f32 it stores
    if not param.minimum <= stored <= param.maximum:
        raise ParameterError(f"{param.name}: {text} is outside [{param.minimum:g}, {param.maximum:g}]")
    if param.param_type in _WHOLE and not value.is_integer():
        raise ParameterError(f"{param.name}: {text} is not a whole number ({param.param_type.name.lower()})")
    return value


class ParamTable:
    """Parameters by name, in index order."""

    def __init__(self, params: list[Parameter] | None = None) -> None:
        self._by_name: dict[str, Parameter] = {p.name: p for p in params or []}

    def __len__(self) -> int:
        return len(self._by_name)

    def __iter__(self):  # type: ignore[no-untyped-def]
        return iter(sorted(self._by_name.values(), key=lambda p: p.index))

    def __contains__(self, name: str) -> bool:
        return name in self._by_name

    def update(self, param: Parameter) -> None:
        self._by_name[param.name] = param

    def get(self, name: str) -> Parameter:
        try:
            return self._by_name[name]
        except KeyError:
            close = [n for n in self._by_name if name.lower() in n.lower()]
            hint = f" (did you mean {', '.join(close)}?)" if close else ""
            raise ParameterError(f"unknown parameter {name!r}{hint}") from None

    def values(self) -> dict[str, float]:
        return {p.name: p.value for p in self}

    def to_json(self) -> list[dict[str, object]]:
        return [{**asdict(p), "param_type": p.param_type.name.lower()} for p in self]

    @classmethod
    def from_json(cls, rows: list[dict[str, object]]) -> ParamTable:
        params = []
        for row in rows:
            data = dict(row)
            data["param_type"] = ParamType[str(data["param_type"]).upper()]
            params.append(Parameter(**data))  # type: ignore[arg-type]
        return cls(params)


def cache_dir() -> Path:
    """$DIVE_CACHE_DIR, else the platform's cache folder for dive (~/.cache/dive on Linux, honouring XDG)."""
    override = os.environ.get("DIVE_CACHE_DIR")
    if override:
        return Path(override)
    import platformdirs  # only sessions that cache a parameter table pay for it

    return Path(platformdirs.user_cache_dir("dive"))


def cache_path(definitions_hash: int, agent_id: int) -> Path:
    return cache_dir() / f"params-{definitions_hash:08x}-{agent_id:08x}.json"


def save_cached(table: ParamTable, definitions_hash: int, agent_id: int) -> None:
    """Best effort: a read-only home must not stop a session."""
    path = cache_path(definitions_hash, agent_id)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp = path.with_suffix(".tmp")
        tmp.write_text(json.dumps(table.to_json(), indent=1))
        tmp.replace(path)
    except OSError:
        pass


def load_cached(definitions_hash: int, agent_id: int) -> ParamTable | None:
    try:
        return ParamTable.from_json(json.loads(cache_path(definitions_hash, agent_id).read_text()))
    except (OSError, ValueError, KeyError, TypeError):
        return None
