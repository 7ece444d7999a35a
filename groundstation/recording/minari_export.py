"""`dive log export --format minari`: a recording's learning episodes as a Minari offline-RL dataset.

Each episode becomes one Minari episode in the terms of `DivingAgent-v0` (simulator/gym/env.py), so
`minari.load_dataset(id).recover_environment()` gives the simulated task the data fits:

- observation t: [measured depth m, the velocity the learner saw m/s, actuator command minus the
  episode's window centre deg], as the environment observes before acting;
- action t: the learner's action of SAMPLE t (0 decrease, 1 increase volume);
- reward t: the reward SAMPLE t+1 reports (the one the agent received for action t);
- terminated: the episode ended in failure (left the learning region); truncated: success (the time
  limit) or aborted by a command.

Episodes are told apart by boot, learner generation and episode number (several files, boots or learner
restarts make one dataset; each step's infos name them). An
episode with a hole in its samples that backfill never filled is left out, not invented, and so is
an episode that has no EPISODE_END (still open when the recording stopped).
"""

from __future__ import annotations

import os
import re
import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from groundstation.errors import RecordingError
from groundstation.recording.environments import differences, environment, group_name, tidy_number
from groundstation.recording.files import RecordingParts
from groundstation.recording.tables import Recording
from protocol import Action, EndReason, Mode

ENV_ID = "DivingAgent-v0"
ENV_ENTRY_POINT = "simulator.gym.env:_make"  # resolved by gymnasium at load time, not imported here
NAMESPACE = "diving_agent"
# DivingAgent-v0's observation bounds (simulator/gym/env.py): the same numbers, checked by a test.
OBS_LOW = (-1.0, -5.0, -130.0)
OBS_HIGH = (12.0, 5.0, 130.0)


@dataclass(frozen=True)
class MinariExport:
    dataset_id: str
    root: Path
    episodes: int
    steps: int
    left_out: int  # episodes with holes or without an end


def dataset_id_for(path: Path) -> str:
    """A Minari dataset id from a recording's file name: diving_agent/<name>-v0."""
    name = re.sub(r"[^A-Za-z0-9_]+", "_", path.stem).strip("_") or "recording"
    return f"{NAMESPACE}/{name}-v0"


@dataclass(frozen=True)
class MinariGroup:
    """Recordings of one environment, exported as one dataset."""

    dataset_id: str
    environment: dict[str, str]
    recordings: list[RecordingParts]


def plan_groups(recordings: list[RecordingParts], name: str) -> tuple[list[MinariGroup], list[str]]:
    """The recordings grouped by environment (environments.py), one dataset id each, and what differs among the
    groups ([] for one group). One group keeps the dataset name `name`; several add each group's name to it."""
    groups: dict[tuple[tuple[str, str], ...], list[RecordingParts]] = {}
    for recording in recordings:
        groups.setdefault(tuple(sorted(environment(_metadata(recording)).items())), []).append(recording)
    envs = [dict(key) for key in groups]
    base = re.sub(r"[^A-Za-z0-9_]+", "_", name).strip("_") or "recording"
    planned = [MinariGroup(f"{NAMESPACE}/{base}-v0" if len(groups) == 1 else
                           f"{NAMESPACE}/{base}_{group_name(env, envs)}-v0", env, members)
               for env, members in zip(envs, groups.values(), strict=True)]
    return planned, differences(envs)


def _metadata(recording: RecordingParts) -> dict[str, list[dict[str, str]]]:
    """Every metadata record of the recording's files, in order: the header's, and the parameter table the run
    wrote once the agent had sent it (often after the header; a header alone would split one environment in two)."""
    from groundstation.mcap_io import read_recording
    from groundstation.mcap_io.indexed import open_indexed

    merged: dict[str, list[dict[str, str]]] = {}
    for path in recording.files:
        indexed = open_indexed(path)
        metadata = indexed.metadata if indexed is not None else read_recording(path, set()).metadata
        for name, entries in metadata.items():
            merged.setdefault(name, []).extend(entries)
    return merged


def export_minari(recording: Recording, dataset_id: str, root: Path | None) -> MinariExport:
    """Write the dataset under `root` (Minari's own datasets folder when None); refuses to overwrite."""
    if root is not None:
        os.environ["MINARI_DATASETS_PATH"] = str(root.resolve())
    try:
        import gymnasium
        import minari
        from minari.data_collector.episode_buffer import EpisodeBuffer
        from minari.storage.datasets_root_dir import get_dataset_path
    except ImportError as e:
        raise RecordingError("--format minari needs minari: pip install -e '.[minari]' in the checkout "
                             "(or pip install minari)") from e
    if get_dataset_path(dataset_id).exists():
        raise RecordingError(f"a Minari dataset {dataset_id} already exists under "
                             f"{get_dataset_path().resolve()}; choose another --out or remove it")
    buffers, left_out = episode_buffers(recording, EpisodeBuffer)
    if not buffers:
        raise RecordingError("the recording holds no complete learning episode to export")
    env_spec = gymnasium.envs.registration.EnvSpec(
        id=ENV_ID, entry_point=ENV_ENTRY_POINT, kwargs=_env_kwargs(recording)
    )
    agent = recording.agent
    with warnings.catch_warnings():
        # Minari advises a code permalink, an author e-mail and an evaluation env: none apply here.
        warnings.simplefilter("ignore", UserWarning)
        _create(minari, dataset_id, buffers, env_spec, gymnasium, agent, recording)
    return MinariExport(dataset_id, get_dataset_path().resolve(), len(buffers),
                        sum(len(b.rewards) for b in buffers), left_out)


def _create(minari: Any, dataset_id: str, buffers: list[Any], env_spec: Any, gymnasium: Any,
            agent: dict[str, str], recording: Recording) -> None:
    minari.create_dataset_from_buffers(
        dataset_id=dataset_id, buffer=buffers, env=env_spec,
        observation_space=gymnasium.spaces.Box(np.array(OBS_LOW), np.array(OBS_HIGH), dtype=np.float64),
        action_space=gymnasium.spaces.Discrete(2),
        algorithm_name=f"on-board learner of {agent.get('name', 'the agent')} (node {_hex(agent.get('node_id', '?'))})",
        author="dive log export", data_format="arrow",
        description=(f"Learning episodes recorded by dive from {', '.join(str(f) for f in recording.files)}; "
                     f"boots {recording.boots}; environment {environment(recording.metadata)}; "
                     f"agent { {k: _hex(v) if k in ('node_id', 'boot_id') else v for k, v in agent.items()} }; "
                     f"parameters { {k: tidy_number(v) for k, v in recording.parameters.items()} }"),
    )


def _hex(text: str) -> str:
    """A node or boot id in hex, as dive status, log info and the file names show it."""
    return f"{int(text):08x}" if text.isdigit() else text


# The agent's parameters that set the plant's side of the task (PlantParams fields): the agent's own table wins over
# the preset's figures (the C firmware keeps its own defaults: 2.1 deg steps in a +/- 19.5 deg window on any plant).
_PLANT_PARAMETERS = (("target_depth_m", "target_depth_m"), ("action_step_deg", "action_step_deg"),
                     ("action_win_deg", "action_window_deg"), ("control_dt_s", "control_period_s"),
                     ("success_time_s", "episode_limit_s"))


def _env_kwargs(recording: Recording) -> dict[str, Any]:
    """make() options of DivingAgent-v0 that match the recorded task: the plant preset and learner the run named
    (a sim:// run; a real agent's plant is the water: the default plant stands in), the agent's parameters (its
    grid, and the plant figures it sets: step, window, period, target, success time, start at rest)."""
    params = recording.parameters
    env = environment(recording.metadata)
    kwargs: dict[str, Any] = {}
    if env["preset"] != "unknown":
        kwargs["preset"] = env["preset"]
    if env["learner"] != "unknown":
        kwargs["learner"] = env["learner"]
    for name in ("z_tol_m", "zdot_tol_mps"):
        if name in params:
            kwargs[name] = float(tidy_number(params[name]))
    for wire_name, option in (("z_cells", "z_cells"), ("zdot_cells", "zdot_cells"), ("act_bins", "actuator_bins")):
        if wire_name in params:
            kwargs[option] = int(float(params[wire_name]))
    plant = {field: float(tidy_number(params[name])) for name, field in _PLANT_PARAMETERS if name in params}
    if "start_at_rest" in params:
        plant["start_with_recovery"] = not float(params["start_at_rest"])
    if env["firmware"] == "c":
        plant["use_observer"] = True  # the firmware's learner sees its own observer's estimate, whatever the preset
    if plant:
        kwargs["params"] = plant
    return kwargs


def episode_buffers(recording: Recording, buffer_type: type) -> tuple[list[Any], int]:
    samples = recording.samples()
    learning = samples[samples["mode"] == int(Mode.LEARNING)] if len(samples) else samples
    step_deg = action_step_deg(recording)
    buffers: list[Any] = []
    left_out = 0
    for row in recording.episodes():
        if row["outcome"] not in {r.name.lower() for r in EndReason}:
            left_out += 1
            continue
        rows = learning[(learning["boot"] == row["boot"]) & (learning["generation"] == row["generation"])
                        & (learning["episode"] == row["episode"])]
        if len(rows) < 2 or np.any(np.diff(rows["sample"]) != 1) or rows["sample"][-1] != row["last_sample"]:
            left_out += 1  # a hole backfill never filled, or its end is missing: leave it out
            continue
        buffers.append(_buffer(buffer_type, len(buffers), rows, row["outcome"], step_deg))
    return buffers, left_out


def _buffer(buffer_type: type, episode_id: int, rows: NDArray[np.void], outcome: str, step_deg: float) -> Any:
    actions = rows["action"][:-1].astype(np.int64)
    if np.any(actions == int(Action.NONE)):
        actions = np.where(actions == int(Action.NONE), 0, actions)  # cannot happen inside an episode
    observations = episode_observations(rows["depth_m"], rows["velocity_mps"], rows["actuator_cmd_deg"],
                                        int(rows["action"][0]), step_deg)
    n = len(actions)
    terminations = np.zeros(n, dtype=bool)
    truncations = np.zeros(n, dtype=bool)
    terminations[-1] = outcome == EndReason.FAILURE.name.lower()
    truncations[-1] = not terminations[-1]
    return buffer_type(
        id=episode_id, observations=observations, actions=actions,
        rewards=rows["reward"][1:].astype(np.float64), terminations=terminations, truncations=truncations,
        # Lists, not 1-D arrays: minari 0.5's arrow storage cannot read back a 1-D info array.
        infos={"state": rows["state"].tolist(), "sample": rows["sample"].tolist(), "t_us": rows["t_us"].tolist(),
               "boot": rows["boot"].tolist(), "generation": rows["generation"].tolist(),
               "episode": rows["episode"].tolist()},
    )


def episode_observations(depth_m: Any, velocity_mps: Any, cmd_deg: Any, first_action: int, step_deg: float
                         ) -> NDArray[np.float64]:
    """DivingAgent-v0's observations of one episode's LEARNING samples in order: [depth, velocity, actuator
    command before the step minus the episode's window centre], clipped to the environment's bounds."""
    cmd = np.asarray(cmd_deg, dtype=np.float64)
    # SAMPLE t carries the command after action t; the window centre is the command before the first.
    centre = cmd[0] - (step_deg if first_action == int(Action.INCREASE_VOLUME) else -step_deg)
    before = np.concatenate(([centre], cmd[:-1]))
    observations = np.column_stack([np.asarray(depth_m, dtype=np.float64),
                                    np.asarray(velocity_mps, dtype=np.float64), before - centre])
    return np.clip(observations, OBS_LOW, OBS_HIGH)


def action_step_deg(recording: Recording) -> float:
    """The learner's actuator step: the recorded parameter, else the median step of its LEARNING samples."""
    value = recording.parameters.get("action_step_deg")
    if value is not None:
        return float(value)
    samples = recording.samples()
    learning = samples[samples["mode"] == int(Mode.LEARNING)] if len(samples) else samples
    steps = np.abs(np.diff(learning["actuator_cmd_deg"])) if len(learning) > 1 else np.zeros(0)
    steps = steps[steps > 1e-6]
    if not len(steps):
        raise RecordingError("the recording states no action_step_deg and holds no learner step to infer it")
    return float(np.median(steps))
