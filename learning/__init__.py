"""The paper's model-based value-function learner and its successors (numpy/numba, no I/O)."""

from learning.config import LearnerConfig, ModelForm, n_states, terminal_state
from learning.errors import LearnerConfigError, LearningError
from learning.learner import Learner, learner_memory_bytes, model_memory_bytes, state_index
from learning.presets import VELOCITY_FILTER, learner_help, learner_names, learner_preset, resolve_learner

__all__ = [
    "VELOCITY_FILTER",
    "Learner",
    "LearnerConfig",
    "LearnerConfigError",
    "LearningError",
    "ModelForm",
    "learner_help",
    "learner_names",
    "learner_preset",
    "learner_memory_bytes",
    "model_memory_bytes",
    "n_states",
    "resolve_learner",
    "state_index",
    "terminal_state",
]
