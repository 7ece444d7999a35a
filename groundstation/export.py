"""`dive log export`: samples as CSV, or an offline-RL dataset (s, a, r, s', terminated, truncated) as .npz."""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np

from groundstation.errors import RecordingError
from groundstation.mcap_io import iter_messages
from protocol import Action, EndReason, Mode


def _samples_and_ends(path: Path) -> tuple[list[dict[str, object]], dict[int, int]]:
    samples: dict[int, dict[str, object]] = {}
    ends: dict[int, int] = {}
    for msg in iter_messages(path, {"/agent/SAMPLE", "/agent/EPISODE_END"}):
        body = msg.json()
        if msg.topic == "/agent/SAMPLE":
            body["log_time_ns"] = msg.log_time_ns
            samples.setdefault(int(body["sample"]), body)
        else:
            ends[int(body["episode"])] = int(body["reason"])
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
    learning = [r for r in rows if r["mode"] == Mode.LEARNING and r["episode"] in ends]
    cols: dict[str, list[float]] = {k: [] for k in (
        "episode", "state", "action", "reward", "next_state", "terminated", "truncated",
        "depth_m", "velocity_mps", "next_depth_m", "next_velocity_mps")}
    for now, nxt in zip(learning, learning[1:], strict=False):
        if nxt["episode"] != now["episode"] or nxt["sample"] != int(now["sample"]) + 1:  # type: ignore[call-overload]
            continue
        if now["action"] == Action.NONE:
            continue
        episode = int(now["episode"])  # type: ignore[call-overload]
        values = {"episode": episode, "state": now["state"], "action": now["action"], "reward": nxt["reward"],
                  "next_state": nxt["state"], "depth_m": now["depth_m"], "velocity_mps": now["velocity_mps"],
                  "next_depth_m": nxt["depth_m"], "next_velocity_mps": nxt["velocity_mps"],
                  "terminated": 0, "truncated": 0}
        for key, value in values.items():
            cols[key].append(float(value))  # type: ignore[arg-type]
    # mark each episode's final transition by how the episode ended
    episodes = np.asarray(cols["episode"], dtype=np.int64)
    terminated = np.zeros(len(episodes), dtype=bool)
    truncated = np.zeros(len(episodes), dtype=bool)
    for episode, reason in ends.items():
        index = np.flatnonzero(episodes == episode)
        if len(index):
            terminated[index[-1]] = reason == EndReason.FAILURE
            truncated[index[-1]] = reason != EndReason.FAILURE
    if not len(episodes):
        raise RecordingError(f"{path} holds no learning transitions to export")
    try:
        np.savez_compressed(
            target, episode=episodes,
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
