"""The conformance checks' registry: each check names its SPEC.md section and quotes the sentence it tests."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from enum import StrEnum
from typing import Any

from groundstation.check.errors import CheckFailed
from groundstation.check.probe import Probe


class Result(StrEnum):
    PASS = "PASS"
    FAIL = "FAIL"
    SKIP = "SKIP"


CheckFunction = Callable[[Probe], str | None]


@dataclass(frozen=True)
class Check:
    """One conformance check: `run(probe)` returns a detail line or raises CheckFailed / CheckSkipped."""

    id: str  # section.name, e.g. "ack.unknown_command"
    section: str  # the SPEC.md section (number and title) whose sentence is tested
    sentence: str  # the spec sentence, quoted
    run: CheckFunction
    requires_motion: bool = False  # would move a real agent or change its learned model
    requires_key: bool = False  # needs --key-file: the agent must hold the same key


@dataclass(frozen=True)
class Outcome:
    check: Check
    result: Result
    detail: str
    seconds: float

    def as_dict(self) -> dict[str, Any]:
        c = self.check
        return {"id": c.id, "section": c.section, "result": self.result.value, "detail": self.detail,
                "sentence": c.sentence, "requires_motion": c.requires_motion, "requires_key": c.requires_key,
                "seconds": round(self.seconds, 3)}


@dataclass
class Registry:
    """Checks in the order they run (module by module, declaration order inside a module)."""

    checks: list[Check] = field(default_factory=list)

    def add(self, check: Check) -> None:
        if any(c.id == check.id for c in self.checks):
            raise ValueError(f"two checks named {check.id}")
        self.checks.append(check)


REGISTRY = Registry()


def check(check_id: str, section: str, sentence: str, *, motion: bool = False,
          key: bool = False) -> Callable[[CheckFunction], CheckFunction]:
    """Register a check function under `check_id` (declaration order is run order)."""

    def register(func: CheckFunction) -> CheckFunction:
        REGISTRY.add(Check(check_id, section, " ".join(sentence.split()), func, motion, key))
        return func

    return register


def expect(condition: bool, detail: str) -> None:
    """CheckFailed with `detail` unless `condition`."""
    if not condition:
        raise CheckFailed(detail)
