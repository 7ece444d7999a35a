"""Plant families: per-parameter ranges or distributions from a TOML file; each trial draws its own plant.

File format (one table per PlantParams field; docs/families/tank.toml is an example):

    [backlash_deg]
    uniform = [0.0, 2.0]          # low, high
    [drag_kgpm]
    normal = [1.0, 0.2]           # mean, standard deviation
    min = 0.5                     # optional clips, for any distribution
    [pressure_noise_pa]
    choice = [6.5, 13.0]          # one of the values, equally likely
    [added_mass_kg]
    value = 0.12                  # a fixed value

Trial t of seed k draws from numpy's generator seeded with (k, t, 2) (streams 0 and 1 are the trial's
learner and environment), the fields in sorted order: the same seed and trial draw the same plant here,
in a sweep or on any cluster.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from simulator.errors import ParamsError
from simulator.parameters import PlantParams, read_param_table, with_overrides

_KINDS = ("uniform", "normal", "choice", "value")
_NUMERIC = {f.name for f in dataclasses.fields(PlantParams) if f.type != "bool"}


@dataclass(frozen=True)
class Spread:
    """How one parameter varies across trials."""

    kind: str  # one of _KINDS
    args: tuple[float, ...]
    low: float = -math.inf  # clip after drawing
    high: float = math.inf

    def draw(self, rng: np.random.Generator) -> float:
        if self.kind == "uniform":
            x = float(rng.uniform(self.args[0], self.args[1]))
        elif self.kind == "normal":
            x = float(rng.normal(self.args[0], self.args[1]))
        elif self.kind == "choice":
            x = float(self.args[int(rng.integers(0, len(self.args)))])
        else:
            x = self.args[0]
        return min(max(x, self.low), self.high)

    def describe(self) -> str:
        text = {"uniform": "U({0:g}, {1:g})", "normal": "N({0:g}, {1:g})", "value": "{0:g}"}.get(self.kind)
        body = text.format(*self.args) if text else "one of " + ", ".join(f"{a:g}" for a in self.args)
        clips = [f"min {self.low:g}"] if self.low > -math.inf else []
        clips += [f"max {self.high:g}"] if self.high < math.inf else []
        return body + (f" ({', '.join(clips)})" if clips else "")


@dataclass(frozen=True)
class PlantFamily:
    """A plant family: its source file and one Spread per varied parameter."""

    path: str
    spreads: dict[str, Spread]

    def draw(self, base: PlantParams, seed: int, trial: int) -> PlantParams:
        """The plant of trial `trial` of seed `seed`: base with every spread parameter drawn."""
        rng = np.random.default_rng([seed, trial, 2])
        drawn = {name: self.spreads[name].draw(rng) for name in sorted(self.spreads)}
        try:
            return with_overrides(base, drawn)
        except ParamsError as e:
            raise ParamsError(
                f"plant family {self.path}: seed {seed} trial {trial} drew an unusable plant: {e}") from None

    def describe(self) -> dict[str, str]:
        return {name: self.spreads[name].describe() for name in sorted(self.spreads)}


def _number(path: Path, name: str, value: Any) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
        raise ParamsError(f"plant family {path}: [{name}] needs finite numbers")
    return float(value)


def _spread(path: Path, name: str, table: Any) -> Spread:
    if name not in _NUMERIC:
        raise ParamsError(f"plant family {path}: {name!r} is not a numeric plant parameter")
    if not isinstance(table, dict):
        raise ParamsError(f"plant family {path}: [{name}] must be a table such as uniform = [low, high]")
    kinds = [k for k in table if k in _KINDS]
    unknown = sorted(set(table) - set(_KINDS) - {"min", "max"})
    if len(kinds) != 1 or unknown:
        raise ParamsError(f"plant family {path}: [{name}] needs exactly one of {', '.join(_KINDS)} "
                          f"(and optional min, max){'; unknown: ' + ', '.join(unknown) if unknown else ''}")
    kind = kinds[0]
    raw = table[kind]
    args = tuple(_number(path, name, v) for v in (raw if isinstance(raw, list) else [raw]))
    wanted = {"uniform": 2, "normal": 2, "value": 1}.get(kind)
    if (wanted is not None and len(args) != wanted) or not args:
        raise ParamsError(f"plant family {path}: [{name}] {kind} takes {wanted or 'at least 1'} number(s)")
    if kind == "uniform" and args[0] > args[1]:
        raise ParamsError(f"plant family {path}: [{name}] uniform needs low <= high")
    if kind == "normal" and args[1] < 0:
        raise ParamsError(f"plant family {path}: [{name}] normal needs a standard deviation >= 0")
    low = _number(path, name, table["min"]) if "min" in table else -math.inf
    high = _number(path, name, table["max"]) if "max" in table else math.inf
    return Spread(kind, args, low, high)


def load_family(path: Path, base: PlantParams) -> PlantFamily:
    """The family of a TOML/JSON file, checked by drawing trial 0 of seed 0 on base (one clear line if bad)."""
    table = read_param_table(path, key="parameter")
    if not table:
        raise ParamsError(f"plant family {path} varies no parameter")
    family = PlantFamily(str(path), {name: _spread(path, name, value) for name, value in table.items()})
    family.draw(base, 0, 0)
    return family


def family_summary(family: PlantFamily, plants: list[PlantParams]) -> dict[str, Any]:
    """summary.json's record of a family study: the spreads and every trial's drawn values."""
    names = sorted(family.spreads)
    return {
        "plant_family": {"file": family.path, "spreads": family.describe()},
        "trial_plants": [{name: getattr(p, name) for name in names} for p in plants],
    }
