"""DivingAgent-v0: the learner's task as a Gymnasium environment over the compiled episode kernels.

May import plant; never agent, serve or study.
"""

import gymnasium

ENV_ID = "DivingAgent-v0"

if ENV_ID not in gymnasium.registry:
    # Registered by name only: the environment's module (and numba's kernels) load on gymnasium.make.
    # 3000 steps = 300 s at the paper's 0.1 s loop; the environment truncates there itself.
    gymnasium.register(id=ENV_ID, entry_point="simulator.gym.env:_make", max_episode_steps=None)
