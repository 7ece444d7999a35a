"""Reading a `dive run` recording back with the mcap library itself, and the checks the reliability tests share."""

from __future__ import annotations

import json
import subprocess
import sys
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from mcap.reader import make_reader

from tests.simulator.agent_client import ROOT

DIVE_MAIN = "import sys; sys.argv[0] = 'dive'; from groundstation.cli.app import main; main()"


def dive(*args: str, env: dict[str, str] | None = None, timeout_s: float = 240) -> subprocess.CompletedProcess[str]:
    """`dive ARGS` as a real process, so a traceback would show on its stderr."""
    return subprocess.run([sys.executable, "-c", DIVE_MAIN, *args], capture_output=True, text=True,
                          timeout=timeout_s, cwd=ROOT, env=env)


@dataclass
class Recording:
    """What a finished recording holds, read by the mcap library's indexed reader."""

    samples: list[tuple[int, bool]] = field(default_factory=list)  # (sample index, backfilled) in file order
    episode_ends: list[int] = field(default_factory=list)
    heartbeats: list[dict[str, Any]] = field(default_factory=list)
    link: list[dict[str, Any]] = field(default_factory=list)  # the /link statistics, 1 Hz
    events: list[dict[str, Any]] = field(default_factory=list)

    @property
    def indices(self) -> list[int]:
        return [i for i, _ in self.samples]

    def missing_and_duplicated(self) -> tuple[list[int], list[int]]:
        """Sample indices missing between the first recorded and the last the agent reported, and duplicates."""
        seen: set[int] = set()
        duplicated = []
        for index in self.indices:
            if index in seen:
                duplicated.append(index)
            seen.add(index)
        reported_end = max((h["log_next_sample"] for h in self.heartbeats), default=0)
        end = max(max(seen) + 1, reported_end)
        return sorted(set(range(min(seen), end)) - seen), duplicated

    def live_in_order(self) -> bool:
        """Samples received live come in strictly increasing order (backfilled ones fill the holes later)."""
        live = [i for i, backfilled in self.samples if not backfilled]
        return all(a < b for a, b in zip(live, live[1:], strict=False))


def read(path: Path) -> Recording:
    rec = Recording()
    with path.open("rb") as f:
        for _, channel, message in make_reader(f).iter_messages(log_time_order=False):
            topic = channel.topic
            if topic == "/agent/SAMPLE":
                body = json.loads(message.data)
                rec.samples.append((int(body["sample"]), bool(body["_backfilled"])))
            elif topic == "/agent/EPISODE_END":
                rec.episode_ends.append(int(json.loads(message.data)["episode"]))
            elif topic == "/agent/HEARTBEAT":
                rec.heartbeats.append(json.loads(message.data))
            elif topic == "/link":
                rec.link.append(json.loads(message.data))
            elif topic == "/event":
                rec.events.append(json.loads(message.data))
    return rec


def assert_complete(rec: Recording, episodes: int) -> None:
    """Every sample the agent produced is held once, live ones in order; the episodes asked for ended."""
    missing, duplicated = rec.missing_and_duplicated()
    assert not missing, f"{len(missing)} samples missing, e.g. {missing[:10]}"
    assert not duplicated, f"{len(duplicated)} samples recorded twice, e.g. {duplicated[:10]}"
    assert rec.live_in_order()
    assert len(set(rec.episode_ends)) >= episodes
