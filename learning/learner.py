"""The paper's learner as a thin Python class over the compiled kernels the batch study also runs."""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numpy.typing import NDArray

from learning.acting import explore_probability, select_action_kernel, state_index_kernel
from learning.config import LearnerConfig, ModelForm, kernel_spec, n_states
from learning.errors import LearningError
from learning.model import N_ACTIONS, ModelArrays, dense_counts, export_model_kernel, record_transition
from learning.planning import plan_kernel
from learning.rng import new_stream
from learning.shared import (
    allocate_arrays,
    record_shared,
    shared_dense_counts,
    shared_memory_bytes,
    state_cell_code,
)
from learning.shared_plan import plan_due, plan_shared_kernel, shared_q_kernel
from learning.spec import KernelSpec, direct_entry

_REWARD_SUM_BYTES = 4  # float32 per (s, a) on the Teensy
_COUNT_BYTES = 2  # uint16
_VALUE_BYTES = 4  # float32 v(s)
_POLICY_BYTES = 1  # uint8 pi(s)


def state_index(
    depth_m: float,
    velocity_mps: float,
    target_depth_m: float,
    config: LearnerConfig,
    actuator_fraction: float = 0.0,
) -> int:
    """The state of (depth, velocity[, actuator position in -1..1 of its window]); S-1 is terminal."""
    return int(
        state_index_kernel(
            float(depth_m), float(velocity_mps), float(target_depth_m), float(actuator_fraction),
            kernel_spec(config),
        )
    )


def model_memory_bytes(config: LearnerConfig) -> int:
    """Bytes of the model as the Teensy holds it.

    Per-state learners: counts, successor indices (sparse), reward sums (values and policy not counted,
    as before). Shared model: everything it needs, values included (learning/shared.py).
    """
    if config.shared_model:
        return shared_memory_bytes(config.z_cells, config.zdot_cells, config.actuator_bins,
                                   config.sparse_slots, config.dirichlet_weight > 0)
    s = n_states(config)
    pairs = s * N_ACTIONS
    if config.model_form == ModelForm.DENSE:
        return pairs * s * _COUNT_BYTES + pairs * _REWARD_SUM_BYTES
    index_bytes = 1 if s <= 256 else 2
    return pairs * config.sparse_slots * (index_bytes + _COUNT_BYTES) + pairs * _REWARD_SUM_BYTES


def learner_memory_bytes(config: LearnerConfig) -> int:
    """Bytes of the whole learner on the Teensy: the model (model_memory_bytes), values (f32) and policy (u8).

    SPEC.md section 13 adds the snapshot copies and compares the sum with the agent's RAM budget. The
    shared model's count already holds its values and it keeps no policy table (learning/shared.py).
    """
    if config.shared_model:
        return model_memory_bytes(config)
    return model_memory_bytes(config) + n_states(config) * (_VALUE_BYTES + _POLICY_BYTES)


class LearnerArrays(NamedTuple):
    """A learner's live state as its kernels take it, for compiled loops that act and observe many steps at once."""

    spec: KernelSpec
    policy: NDArray[np.int8]
    rng_state: NDArray[np.uint64]
    model: ModelArrays


class Learner:
    """Model-based value-function learner: act, observe, end_episode (value iteration), inspect."""

    def __init__(self, config: LearnerConfig, rng: np.random.Generator) -> None:
        self._config = config
        self._spec = kernel_spec(config)
        self._rng_state = new_stream(rng)
        self.reset()

    def reset(self) -> None:
        """Forget everything: empty model, zero values, a random tie-broken policy, episode 0."""
        s = n_states(self._config)
        self._sparse = self._config.model_form == ModelForm.SPARSE
        self._shared = self._config.shared_model
        self._model = allocate_arrays(self._spec)
        self.evictions = 0
        self._values = np.zeros(s)
        self._q = np.zeros((s, N_ACTIONS))
        self._policy = np.zeros(s, dtype=np.int8)
        self._episode = 0
        self._p_explore = float(explore_probability(0, self._spec))
        # Compiled entries without per-call dispatch (see direct_entry): act and observe run every step.
        self._select = direct_entry(select_action_kernel, self._policy, 0, 0.0, self._spec, self._rng_state)
        m = self._model
        self._record = direct_entry(record_transition, m.succ_idx, m.succ_cnt, m.reward_sum, 0, 0, 0.0, 0, self._sparse)
        self._record_shared = direct_entry(record_shared, m, 0, 0, 0, self._spec)
        self.last_sweeps = self._plan()

    def _plan(self) -> int:
        if self._shared:
            return int(plan_shared_kernel(self._model, self._values, self._q, self._policy, self._spec,
                                          self._rng_state))
        m = self._model
        return int(plan_kernel(m.succ_idx, m.succ_cnt, m.reward_sum, self._values, self._q, self._policy,
                               self._spec, self._rng_state))

    def plan_due(self) -> bool:
        """Whether the end of the episode now would plan (always, unless LearnerConfig.plan_growth is set)."""
        return (not self._shared) or bool(plan_due(self._model, self._spec))

    @property
    def config(self) -> LearnerConfig:
        return self._config

    @property
    def arrays(self) -> LearnerArrays:
        """The live arrays act() and observe() use (replaced by reset()); a loop that acts and observes with
        select_action_kernel, record_transition and record_shared on them adds its evictions to `evictions`."""
        return LearnerArrays(self._spec, self._policy, self._rng_state, self._model)

    @property
    def episode(self) -> int:
        """Completed episodes."""
        return self._episode

    @property
    def p_explore(self) -> float:
        """Exploration probability of the current episode."""
        return self._p_explore

    def act(self, state: int) -> int:
        """0 = a1 (decrease volume), 1 = a2 (increase volume); greedy, flipped with p_explore."""
        self._check_state(state)
        return int(self._select(self._policy, state, self._p_explore, self._spec, self._rng_state))

    def observe(
        self, state: int, action: int, reward: float, next_state: int, next_cell: int | None = None
    ) -> None:
        """Record one transition into the count model (Alg. 3).

        The shared model needs where a terminal successor lies: next_cell, the raw cell code of the
        measurement (learning.shared.raw_cell_kernel); for a live successor its own cell is used if omitted.
        """
        self._check_state(state)
        self._check_state(next_state, allow_terminal=True)
        if action not in (0, 1):
            raise LearningError(f"action must be 0 or 1, got {action}")
        if self._shared:
            if next_cell is None:
                if next_state == self._values.shape[0] - 1:
                    raise LearningError("the shared model needs next_cell for a terminal successor")
                next_cell = int(state_cell_code(next_state, self._spec))
            self.evictions += bool(self._record_shared(self._model, state, action, next_cell, self._spec))
            if self._config.dirichlet_weight == 0:
                return
        m = self._model
        self.evictions += bool(self._record(
            m.succ_idx, m.succ_cnt, m.reward_sum, state, action, reward, next_state, self._sparse
        ))

    def end_episode(self) -> None:
        """Value iteration on the updated model, warm-started from the current values (with plan_growth only
        once the model has grown enough: else last_sweeps is 0 and the policy stays); next episode."""
        self.last_sweeps = self._plan() if self.plan_due() else 0
        self._episode += 1
        self._p_explore = float(explore_probability(self._episode, self._spec))

    @property
    def values(self) -> NDArray[np.float64]:
        """v per state (terminal last, always 0); a copy."""
        return self._values.copy()

    @property
    def q_values(self) -> NDArray[np.float64]:
        """Q[s, a] of the last value iteration; a copy."""
        return self._q.copy()

    def live_q_values(self) -> NDArray[np.float64]:
        """Q[s, a] from the model as it is now and the current values (the shared model: computed, as its
        firmware does; the per-state learners: the last value iteration's, their Q table)."""
        if self._shared:
            return shared_q_kernel(self._model, self._values, self._spec)
        return self.q_values

    @property
    def policy(self) -> NDArray[np.int64]:
        """Greedy action per state (2 = tied, drawn at every step, with ties_per_step); a copy."""
        return self._policy.astype(np.int64)

    @property
    def counts(self) -> NDArray[np.uint16]:
        """Transition counts C[s, s', a] (uint16), exported from whichever form is stored (the shared
        model's: its histograms shifted to each state, see learning.shared.shared_dense_counts)."""
        if self._shared:
            return shared_dense_counts(self._model, self._spec)
        return dense_counts(self._model.succ_idx, self._model.succ_cnt)

    def export_model(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """P[s, s', a] and R[s, a] as dense float arrays (untried rows zero)."""
        return export_model_kernel(self._model.succ_idx, self._model.succ_cnt, self._model.reward_sum)

    @property
    def memory_bytes(self) -> int:
        """Exact bytes of the model on the Teensy (see model_memory_bytes)."""
        return model_memory_bytes(self._config)

    def _check_state(self, state: int, allow_terminal: bool = False) -> None:
        last = self._values.shape[0] - (0 if allow_terminal else 1)
        if not 0 <= state < last:
            raise LearningError(f"state {state} outside 0..{last - 1}")
