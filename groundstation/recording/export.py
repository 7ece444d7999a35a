"""`dive log export`: samples as CSV, or an offline-RL dataset (s, a, r, s', terminated, truncated) as .npz."""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np

from groundstation.errors import RecordingError
from groundstation.recording.minari_export import OBS_HIGH, OBS_LOW, action_step_deg, episode_observations
from groundstation.recording.tables import Recording, open_recording
from protocol import Action, EndReason, Mode

_REASONS = {reason.name.lower(): int(reason) for reason in EndReason}


Key = tuple[int, int, int]  # (boot, generation, episode), as open_recording keys an episode


def _key(row: dict[str, object]) -> Key:
    return int(row["boot"]), int(row["generation"]), int(row["episode"])  # type: ignore[call-overload]


def _samples_and_ends(paths: list[Path]) -> tuple[list[dict[str, object]], dict[Key, int], Recording]:
    """Samples by (boot, index), each once, in order; episode end reasons by (boot, generation, episode).

    Read through open_recording (the notebook API), so the CLI and a notebook see the same rows: sample and
    episode numbers restart at an agent reboot and at a learner restart, each row carries its `boot` (1, 2, ...
    in file order) and `generation`, two boots or chapters are never spliced, and messages whose JSON has the
    wrong shape are left out.
    """
    recording = open_recording(*paths)
    table = recording.samples()
    names = [name for name in table.dtype.names or () if name not in ("_seq", "_flags", "boot", "generation")]
    columns = ["boot", "generation", *names]
    rows = [dict(zip(columns, values, strict=True)) for values in table[columns].tolist()]
    ends = {(int(e["boot"]), int(e["generation"]), int(e["episode"])): _REASONS[str(e["outcome"])]
            for e in recording.episodes() if str(e["outcome"]) in _REASONS}
    return rows, ends, recording


def _files(source: Path | list[Path]) -> tuple[list[Path], str]:
    """One recording's files (a file, or the parts of a split one) and how an error names them."""
    files = source if isinstance(source, list) else [source]
    return files, str(files[0]) if len(files) == 1 else f"{files[0]} and its {len(files) - 1} other part(s)"


def export_csv(source: Path | list[Path], target: Path) -> int:
    """The samples of a recording (a file, or the parts of a split one together) as CSV, one row each."""
    files, path = _files(source)
    rows, _, _ = _samples_and_ends(files)
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


def export_npz(source: Path | list[Path], target: Path) -> int:
    """One row per learner transition: the SAMPLE at step t gives s, a; the one at t+1 gives r and s'.

    The last transition of an episode is `terminated` if it ended in failure (terminal state) and
    `truncated` if it ended by success or abort (time limit, command). Transitions across a missing
    sample are left out rather than invented. The parts of a split recording are read together, so an episode
    that crosses from one part into the next is kept whole.
    """
    files, path = _files(source)
    rows, ends, recording = _samples_and_ends(files)
    learning = [r for r in rows if r["mode"] == Mode.LEARNING and _key(r) in ends]
    _observe(learning, recording)
    cols: dict[str, list[float]] = {k: [] for k in (
        "boot", "generation", "episode", "state", "action", "reward", "next_state", "terminated", "truncated",
        "depth_m", "velocity_mps", "next_depth_m", "next_velocity_mps", "offset_deg", "next_offset_deg")}
    for now, nxt in zip(learning, learning[1:], strict=False):
        if _key(nxt) != _key(now) or nxt["sample"] != int(now["sample"]) + 1:  # type: ignore[call-overload]
            continue
        if now["action"] == Action.NONE:
            continue
        episode = int(now["episode"])  # type: ignore[call-overload]
        values = {"boot": now["boot"], "generation": now["generation"], "episode": episode, "state": now["state"],
                  "action": now["action"], "reward": nxt["reward"],
                  "next_state": nxt["state"], "depth_m": now["depth_m"], "velocity_mps": now["velocity_mps"],
                  "next_depth_m": nxt["depth_m"], "next_velocity_mps": nxt["velocity_mps"],
                  "offset_deg": now["_offset_deg"], "next_offset_deg": nxt["_offset_deg"],
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
    generations = np.asarray(cols["generation"], dtype=np.int64)
    terminated = np.zeros(len(episodes), dtype=bool)
    truncated = np.zeros(len(episodes), dtype=bool)
    for (boot, generation, episode), reason in ends.items():
        index = np.flatnonzero((episodes == episode) & (boots == boot) & (generations == generation))
        if len(index):
            terminated[index[-1]] = reason == EndReason.FAILURE
            truncated[index[-1]] = reason != EndReason.FAILURE
    if not len(episodes):
        raise RecordingError(f"{path} holds no learning transitions to export")
    observation = np.column_stack([cols["depth_m"], cols["velocity_mps"], cols["offset_deg"]])
    next_observation = np.column_stack([cols["next_depth_m"], cols["next_velocity_mps"], cols["next_offset_deg"]])
    try:
        with target.open("wb") as f:  # a file, not a name: numpy would add ".npz" to a name without it
            np.savez_compressed(
                f, boot=boots, generation=generations, episode=episodes,
                state=np.asarray(cols["state"], dtype=np.int64), action=np.asarray(cols["action"], dtype=np.int64),
                reward=np.asarray(cols["reward"], dtype=np.float32),
                next_state=np.asarray(cols["next_state"], dtype=np.int64),
                terminated=terminated, truncated=truncated,
                # DivingAgent-v0's (and the Minari export's) observation: depth, velocity, actuator offset
                observation=np.clip(observation, OBS_LOW, OBS_HIGH),
                next_observation=np.clip(next_observation, OBS_LOW, OBS_HIGH),
            )
    except OSError as e:
        raise RecordingError(f"cannot write {target}: {e.strerror or e}") from e
    return len(episodes)


def _observe(learning: list[dict[str, object]], recording: Recording) -> None:
    """Each row's actuator offset as DivingAgent-v0 observes it (`_offset_deg`), episode by episode; NaN when the
    recording states no action step and its learner never moved the actuator (the window centre is unknown)."""
    if not learning:
        return
    try:
        step_deg = action_step_deg(recording)
    except RecordingError:  # no step stated and none taken: the offset from the window centre is unknown
        step_deg = float("nan")
    start = 0
    for end in range(1, len(learning) + 1):
        if end < len(learning) and _key(learning[end]) == _key(learning[start]):
            continue
        rows = learning[start:end]
        cmd = [float(r["actuator_cmd_deg"]) if r["actuator_cmd_deg"] is not None else np.nan  # type: ignore[arg-type]
               for r in rows]
        observed = episode_observations(np.zeros(len(rows)), np.zeros(len(rows)), cmd, int(rows[0]["action"]),  # type: ignore[call-overload]
                                        step_deg)
        for row, offset in zip(rows, observed[:, 2], strict=True):
            row["_offset_deg"] = float(offset)
        start = end
