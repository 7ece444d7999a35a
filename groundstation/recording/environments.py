"""What makes recordings one environment (issue 28 item 2): the key an offline-RL export groups recordings by.

Two recordings are one environment when the same plant (preset, plant parameter file), the same on-board program
and learner, the same grid, target and learning region produced them: their transitions come from one MDP. How a
run was played (speed, seed, link faults) does not change the MDP and is left out.
"""

from __future__ import annotations

import math
import re

import numpy as np

Header = dict[str, list[dict[str, str]]]

# sim:// options that change how a run is played, not the environment (groundstation/links/sim.py: `dive sim`)
_HOW_PLAYED = {"speed", "seed", "drop", "corrupt", "delay", "disconnect_every", "blackout_below", "key_file",
               "state_dir", "report"}
# The agent parameters that define the task the learner faces (grid, target, region, step, time limit, reward)
TASK_PARAMETERS = ("target_depth_m", "z_tol_m", "zdot_tol_mps", "z_cells", "zdot_cells", "act_bins",
                   "action_step_deg", "action_win_deg", "control_dt_s", "success_time_s", "term_reward",
                   "depth_only_term")


def wire_float32(value: float) -> float:
    """A float32 field widened to float64 (2.799999952316284) as the shortest number that is the same float32
    (2.8): what the agent sent, without the widening's noise, in JSON and text."""
    return float(str(np.float32(value))) if math.isfinite(value) else value


def tidy_number(text: str) -> str:
    """A recorded number as people write it: a float32 parameter's 0.10000000149011612 is 0.1 (the shortest text
    that is the same float32), 10.0 is 10; anything else unchanged."""
    try:
        value = float(text)
    except ValueError:
        return text
    if not math.isfinite(value):
        return text
    if value == int(value) and abs(value) < 2**53:
        return str(int(value))
    single = np.float32(value)
    return str(single) if float(single) == value else repr(value)


def tidy_value(value: float) -> float:
    """tidy_number for a number: a float32 value as the float its shortest text means (9.8, not 9.800000190734863)."""
    return float(tidy_number(repr(value))) if math.isfinite(value) else value


def environment(header: Header) -> dict[str, str]:
    """A recording's environment from its header: preset, firmware, learner, plant parameters, task parameters."""
    session = (header.get("session") or [{}])[0]
    parameters = (header.get("parameters") or [{}])[-1]
    simulated = session.get("url", "").startswith("sim://")
    default = "paper" if simulated else "unknown"  # a real agent: its plant is the water, its program unknown
    env = {"preset": session.get("sim_preset", default), "learner": session.get("sim_learner", default),
           "firmware": session.get("sim_firmware", "python" if simulated else "unknown")}
    for key, value in session.items():
        name = key.removeprefix("sim_")
        if key.startswith("sim_") and name not in _HOW_PLAYED and name not in env:
            env[name] = value  # e.g. params: the plant parameter file
    for name in TASK_PARAMETERS:
        if name in parameters:
            env[name] = tidy_number(parameters[name])
    return env


def differences(envs: list[dict[str, str]]) -> list[str]:
    """What differs among environments, one `name: a, b` entry per differing key."""
    keys = sorted({k for env in envs for k in env})
    out = []
    for key in keys:
        values = sorted({env.get(key, "-") for env in envs})
        if len(values) > 1:
            out.append(f"{key}: {', '.join(values)}")
    return out


def group_name(env: dict[str, str], others: list[dict[str, str]]) -> str:
    """A short name for an environment among `others`: preset, learner and firmware, then what else differs."""
    parts = [env["preset"], env["learner"], env["firmware"]]
    varying = {entry.split(":")[0] for entry in differences(others)} - {"preset", "learner", "firmware"}
    parts += [f"{key}{env.get(key, '-')}" for key in sorted(varying)]
    return re.sub(r"[^A-Za-z0-9_]+", "_", "_".join(parts)).strip("_")
