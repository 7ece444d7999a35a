"""The learner's configuration: grid, discounting, exploration, model form and the errata switches."""

from __future__ import annotations

from dataclasses import dataclass
from enum import IntEnum

from learning.errors import LearnerConfigError
from learning.spec import KernelSpec, kernel_tuple_type, to_kernel_tuple

MAX_VELOCITY_DIFF_STEPS = 16  # depth history the environment keeps for the k-step difference


class ModelForm(IntEnum):
    """How the transition counts are stored."""

    DENSE = 0  # uint16 C[s, a, s']: 41 KB at 101 states, what the paper's simulation could afford
    SPARSE = 1  # a few (uint8 successor, uint16 count) slots per (s, a): what fits the Teensy


@dataclass(frozen=True)
class LearnerConfig:
    """Everything the learner of paper Section III needs; defaults are the paper's simulation values."""

    z_cells: int = 10  # depth cells across the learning region (paper Fig. 2)
    zdot_cells: int = 10  # velocity cells across the learning region (paper Fig. 2)
    z_tol_m: float = 0.1  # half-width of the learning region in depth (paper V-A)
    zdot_tol_mps: float = 0.04  # half-width of the learning region in velocity (paper V-A)
    gamma: float = 0.99  # discount factor (paper V-A)
    vi_tolerance: float = 1e-4  # value iteration stops when max |v_new - v| falls below (paper V-A)
    terminal_reward: float = -10.0  # reward on entering the terminal state (paper V-A)
    p_explore_start: float = 0.10  # exploration probability at episode 0 (paper V-A)
    p_explore_end: float = 0.0  # exploration probability from explore_decay_episodes on (paper V-A)
    explore_decay_episodes: int = 1000  # length of the linear exploration decay (paper V-A)
    depth_only_terminal: bool = False  # authors' MATLAB/firmware: leaving in velocity does not end it
    # Errata switches: True is the literal reading of the printed pseudo-code (diving-agent.md s. 5).
    explore_literal_gt: bool = False  # Alg. 2 "p_rand > p_expl": explores 90 % of the time
    policy_argmin: bool = False  # text: pi(s) = argmin_a q(a, s), wrong with negative rewards
    alg4_printed: bool = False  # Alg. 4 applies P twice: Q = (sum_s' P)(R + gamma P v)
    untried_q_value: float = 0.0  # Q of a pair tried fewer than known_count times; 0 = optimistic
    known_count: int = 1  # 1: the paper; m > 1: R-MAX's "known" threshold
    random_ties: bool = True  # False: np.argmax's habit of always picking a1 on ties
    model_form: ModelForm = ModelForm.SPARSE
    # Successor slots per (s, a): never all taken on the paper's grid; with actuator bins a pair can have more
    # than 12 successors (actuator3 does) and the rarest is evicted (counted: summary.json model.slot_evictions).
    sparse_slots: int = 12
    actuator_bins: int = 1  # > 1 adds the actuator position (relative to neutral) to the state
    in_place_sweeps: bool = False  # Gauss-Seidel value iteration: same fixed point, fewer sweeps
    max_sweeps: int = 100_000  # sweeps per planning call: a safety stop, or a budget (bounded planning)
    # Tie-breaking: False decides a tied state's action once per planning call (it then repeats for the
    # whole next episode, the project's original choice); True draws afresh at every step.
    ties_per_step: bool = False
    # The shared (relocatable) model of learning/shared.py instead of per-state counts.
    shared_model: bool = False
    # > 0 with shared_model: per-state counts as well, the shared histogram their Dirichlet prior of this
    # weight (in pseudo-counts); 0 = the shared histogram alone.
    dirichlet_weight: float = 0.0
    count_bonus: float = 0.0  # MBIE-EB exploration: beta / sqrt(n) added to a pair's reward (0 = off)
    # 0: the velocity the environment gives (true or observer); k: the agent's own k-step depth
    # difference (z_t - z_{t-k}) / (k dt).
    velocity_diff_steps: int = 0
    # Shared model only: the reward of arriving in a cell also loses this many times the |velocity| of
    # the cell's centre (m/s -> reward per step, 0 = the paper's -|z|). It makes rushing at the region's
    # velocity edge cost what it risks (learning/shared.py, cell_reward).
    velocity_penalty: float = 0.0
    # > 0: the velocity the learner sees comes from a filter on its measured depths that predicts with the
    # gear angle it commands (the firmware knows it): states depth, velocity and an acceleration bias (a
    # neutral point off by a few degrees), corrected each step by the depth innovation r with these gains
    # (z += kz r, z' += kv r / dt, bias += kb r / dt^2). An 8-step difference lags the true velocity by
    # ~0.35 s, and more behind a lagging port: the policy then brakes late and its swing grows until it
    # leaves the region (docs/learners.md, "The `hardware` learner, ingredient by ingredient"). 0 = off.
    filter_depth_gain: float = 0.0
    filter_velocity_gain: float = 0.0
    filter_bias_gain: float = 0.0
    # The filter's model, nominal figures (not the plant's): z'' = accel_per_deg (alpha - centre) - drag z'|z'|.
    filter_accel_per_deg: float = 0.0
    filter_drag_per_m: float = 0.0
    # With the filter: the depth the learner sees (its state's depth cell, its reward, leaving the region) is the
    # filter's estimate instead of the raw reading, so that sensor noise does not flicker it between cells.
    filter_depth_state: bool = False
    # Planning's early stop (learning/planning.py plan_rows; 0 = off, the stop at vi_tolerance alone): a call
    # also ends once no state's greedy action has changed for this many sweeps in a row and max |change| is
    # below plan_loose_tolerance. Once learning has settled, most of a call's ~40 sweeps only refine values
    # whose greedy actions no longer move (docs/reproduction.md, "Planning that stops early").
    plan_stable_sweeps: int = 0
    plan_loose_tolerance: float = 0.0
    # Issue 43 item 4: plan only once the model has grown (0 = off, a plan after every episode). An episode's end
    # plans once some type has counted, since the last plan, at least plan_growth times the transitions it had
    # then (at least one): UCRL2's doubling rule at 1 (Jaksch, Ortner and Auer 2010), more often below it. A type
    # seen for the first time always plans; late in learning, when a type's counts move its probabilities by a
    # fraction of a percent an episode, most plans are skipped (learning/shared_plan.py plan_due).
    plan_growth: float = 0.0
    # Issue 43: a smaller step near a hover (0 = off, every step is the plant's action_step_deg). The step is this
    # many degrees while the velocity the learner sees is below fine_speed_mps: a multiple of the velocity cell
    # width keeps the step a function of the velocity cell, which the shared model's types already hold, so
    # pooling over depth stays exact. Chatter between two actions then costs the battery and the hold a fraction
    # of the plant's step; far from a hover the full step still brakes in time.
    fine_step_deg: float = 0.0
    fine_speed_mps: float = 0.0
    # > 0 with the fine step: where the fine step applies, an action that reverses the last one's direction steps
    # this many degrees instead (it takes up a gear's lost motion, which a fine step would spend moving nothing);
    # continuing steps stay fine. Both agents have it (agent parameter fine_reversal_deg; firmware/src/learner.c
    # learner_step_deg).
    fine_reversal_deg: float = 0.0
    # Issue 43, screened (study only; the agents have no parameter for them yet, so they refuse a config with
    # them set): a hold, a step of 0 while the depth error the learner sees is under hold_depth_m and its velocity
    # under hold_speed_mps (both > 0 to apply); a held step is not counted in the shared model, whose types assume
    # every action moves the gear, and a move after a hold reverses the last move, not the held action. With
    # neutral_gain as well a held step goes to the neutral found instead of staying where it is.
    hold_depth_m: float = 0.0
    hold_speed_mps: float = 0.0
    # With a hold to the neutral: the command entering a hold overshoots the neutral by this many degrees in the
    # direction it moves (a gear's output trails its motor by half the lash; the chatter's average is the output's).
    hold_lash_deg: float = 0.0
    # > 0: the action window re-centred on the neutral the learner finds: an average of its own command, updated
    # with this gain at every step where its depth error and velocity are within a quarter of the region's, taken
    # as the window's centre (and the first command) at each hand-over instead of the controller's average.
    neutral_gain: float = 0.0

    def __post_init__(self) -> None:
        if self.z_cells < 1 or self.zdot_cells < 1 or self.actuator_bins < 1:
            raise LearnerConfigError("grid cells and actuator bins must be at least 1")
        if self.z_tol_m <= 0 or self.zdot_tol_mps <= 0:
            raise LearnerConfigError("z_tol_m and zdot_tol_mps must be positive")
        if not 0.0 <= self.gamma < 1.0:
            raise LearnerConfigError("gamma must lie in [0, 1)")
        if self.vi_tolerance <= 0:
            raise LearnerConfigError("vi_tolerance must be positive")
        for p in (self.p_explore_start, self.p_explore_end):
            if not 0.0 <= p <= 1.0:
                raise LearnerConfigError("exploration probabilities must lie in [0, 1]")
        if self.explore_decay_episodes < 1 or self.known_count < 1 or self.sparse_slots < 1:
            raise LearnerConfigError("explore_decay_episodes, known_count and sparse_slots must be >= 1")
        if not 0 <= self.velocity_diff_steps <= MAX_VELOCITY_DIFF_STEPS:
            raise LearnerConfigError(f"velocity_diff_steps must lie in 0..{MAX_VELOCITY_DIFF_STEPS}")
        if self.dirichlet_weight < 0 or self.count_bonus < 0 or self.velocity_penalty < 0:
            raise LearnerConfigError("dirichlet_weight, count_bonus and velocity_penalty must not be negative")
        if self.shared_model and self.sparse_slots > 255:
            raise LearnerConfigError("the shared model holds at most 255 offset slots per type")
        if self.filter_depth_gain < 0 or self.filter_velocity_gain < 0 or self.filter_bias_gain < 0:
            raise LearnerConfigError("filter gains must not be negative")
        if self.filter_depth_state and self.filter_depth_gain <= 0:
            raise LearnerConfigError("filter_depth_state needs the velocity filter (filter_depth_gain > 0)")
        if self.filter_depth_gain > 0 and self.velocity_diff_steps > 0:
            raise LearnerConfigError("choose the velocity filter or the depth difference, not both")
        if self.max_sweeps < 1:
            raise LearnerConfigError("max_sweeps must be >= 1")
        if n_states(self) > 65535:
            raise LearnerConfigError("at most 65535 states (successor indices are uint16)")
        if self.plan_stable_sweeps < 0 or self.plan_loose_tolerance < 0:
            raise LearnerConfigError("plan_stable_sweeps and plan_loose_tolerance must not be negative")
        if min(self.hold_depth_m, self.hold_speed_mps, self.hold_lash_deg) < 0 or not 0.0 <= self.neutral_gain < 1.0:
            raise LearnerConfigError("hold_depth_m, hold_speed_mps and hold_lash_deg must not be negative, "
                                     "neutral_gain in [0, 1)")
        if self.fine_step_deg < 0 or self.fine_speed_mps < 0 or self.fine_reversal_deg < 0:
            raise LearnerConfigError("fine_step_deg, fine_speed_mps and fine_reversal_deg must not be negative")
        if self.plan_stable_sweeps > 0 and not self.shared_model:
            raise LearnerConfigError("the early planning stop (plan_stable_sweeps) is for the shared model only")
        if not 0.0 <= self.plan_growth <= 100.0:
            raise LearnerConfigError("plan_growth must lie in [0, 100]")
        if self.plan_growth > 0 and not self.shared_model:
            raise LearnerConfigError("planning on growth (plan_growth) is for the shared model only")


LearnerSpec = kernel_tuple_type(LearnerConfig, "LearnerSpec")


def kernel_spec(config: LearnerConfig) -> KernelSpec:
    """The config as the named tuple the numba kernels take."""
    return to_kernel_tuple(config, LearnerSpec)


def n_states(config: LearnerConfig) -> int:
    """Number of states including the terminal one (101 with the defaults)."""
    return config.z_cells * config.zdot_cells * config.actuator_bins + 1


def terminal_state(config: LearnerConfig) -> int:
    """Index of the terminal state, always the last one."""
    return n_states(config) - 1
