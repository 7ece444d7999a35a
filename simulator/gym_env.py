"""Old path of simulator.gym.env, kept for one release (0.1.x): import simulator.gym instead."""

from simulator.gym.env import *  # noqa: F403
