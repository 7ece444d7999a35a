"""`dive log export`: samples as CSV, or an offline-RL dataset (s, a, r, s', terminated, truncated) as .npz."""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np

from groundstation.errors import RecordingError
from groundstation.mcap_io import iter_messages
from groundstation.recorded import Boots, json_fields
from protocol import Action, EndReason, Mode


def _samples_and_ends(path: Path) -> tuple[list[dict[str, object]], dict[tuple[int, int], int]]:
    """Samples by (boot, index), each once, in order; episode end reasons by (boot, episode).

    Sample and episode numbers restart at an agent reboot, so each row carries its `boot` (1, 2, ... in file
    order) and two boots are never spliced. Messages whose JSON has the wrong shape are skipped.
    """
    samples: dict[tuple[int, int], dict[str, object]] = {}
    ends: dict[tuple[int, int], int] = {}
    boots = Boots()
    for msg in iter_messages(path, {"/agent/SAMPLE", "/agent/EPISODE_END", "/agent/HELLO"}):
        if msg.topic == "/agent/HELLO":
            boots.hello(msg)
        elif msg.topic == "/agent/SAMPLE":
            body = json_fields(msg, integers=("sample", "episode", "mode", "action", "state"))
            if body is not None:
                body = {"boot": boots.current, **body, "log_time_ns": msg.log_time_ns}
                samples.setdefault((boots.current, body["sample"]), body)
        else:
            end = json_fields(msg, integers=("episode", "reason"))
            if end is not None:
                ends[(boots.current, end["episode"])] = end["reason"]
    return [samples[k] for k in sorted(samples)], ends


def export_csv(path: Path, target: Path) -> int:
    rows, _ = _samples_and_ends(path)
    if not rows:
        raise RecordingError(f"{path} holds no samples to export")
    columns = [c for c in rows[0] if c not in ("_seq", "_flags")]
    try:
        with target.open("w", newline="") as f:
            writer = csv.DictWriter(f, columns, extrasaction="ignore")
            writer.writeheader()
            writer.writerows(rows)
    except OSError as e:
        raise RecordingError(f"cannot write {target}: {e.strerror or e}") from e
    return len(rows)


def export_npz(path: Path, target: Path) -> int:
    """One row per learner transition: the SAMPLE at step t gives s, a; the one at t+1 gives r and s'.

    The last transition of an episode is `terminated` if it ended in failure (terminal state) and
    `truncated` if it ended by success or abort (time limit, command). Transitions across a missing
    sample are left out rather than invented.
    """
    rows, ends = _samples_and_ends(path)
    learning = [r for r in rows if r["mode"] == Mode.LEARNING and (r["boot"], r["episode"]) in ends]
    cols: dict[str, list[float]] = {k: [] for k in (
        "boot", "episode", "state", "action", "reward", "next_state", "terminated", "truncated",
        "depth_m", "velocity_mps", "next_depth_m", "next_velocity_mps")}
    for now, nxt in zip(learning, learning[1:], strict=False):
        if nxt["boot"] != now["boot"] or nxt["episode"] != now["episode"] \
                or nxt["sample"] != int(now["sample"]) + 1:  # type: ignore[call-overload]
            continue
        if now["action"] == Action.NONE:
            continue
        episode = int(now["episode"])  # type: ignore[call-overload]
        values = {"boot": now["boot"], "episode": episode, "state": now["state"], "action": now["action"],
                  "reward": nxt["reward"],
                  "next_state": nxt["state"], "depth_m": now["depth_m"], "velocity_mps": now["velocity_mps"],
                  "next_depth_m": nxt["depth_m"], "next_velocity_mps": nxt["velocity_mps"],
                  "terminated": 0, "truncated": 0}
        try:  # a recorded NaN is null; a value of the wrong type leaves the transition out
            numbers = {key: float("nan") if value is None else float(value)  # type: ignore[arg-type]
                       for key, value in values.items()}
        except (TypeError, ValueError):
            continue
        for key, number in numbers.items():
            cols[key].append(number)
    # mark each episode's final transition by how the episode ended
    episodes = np.asarray(cols["episode"], dtype=np.int64)
    boots = np.asarray(cols["boot"], dtype=np.int64)
    terminated = np.zeros(len(episodes), dtype=bool)
    truncated = np.zeros(len(episodes), dtype=bool)
    for (boot, episode), reason in ends.items():
        index = np.flatnonzero((episodes == episode) & (boots == boot))
        if len(index):
            terminated[index[-1]] = reason == EndReason.FAILURE
            truncated[index[-1]] = reason != EndReason.FAILURE
    if not len(episodes):
        raise RecordingError(f"{path} holds no learning transitions to export")
    try:
        np.savez_compressed(
            target, boot=boots, episode=episodes,
            state=np.asarray(cols["state"], dtype=np.int64), action=np.asarray(cols["action"], dtype=np.int64),
            reward=np.asarray(cols["reward"], dtype=np.float32),
            next_state=np.asarray(cols["next_state"], dtype=np.int64),
            terminated=terminated, truncated=truncated,
            observation=np.column_stack([cols["depth_m"], cols["velocity_mps"]]).astype(np.float32),
            next_observation=np.column_stack([cols["next_depth_m"], cols["next_velocity_mps"]]).astype(np.float32),
        )
    except OSError as e:
        raise RecordingError(f"cannot write {target}: {e.strerror or e}") from e
    return len(episodes)
