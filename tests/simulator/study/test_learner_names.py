"""Plain learner names: the aliases resolve to the recommended presets; `study --help` lists every learner."""

from __future__ import annotations

import os
import subprocess
import sys

from learning import learner_names, learner_preset, resolve_learner
from learning.presets import DESCRIPTIONS


def test_aliases_are_the_recommended_presets() -> None:
    assert learner_preset("hardware") == learner_preset("hardware-lazyplan")
    assert learner_preset("paper-best") == learner_preset("shared")
    assert resolve_learner("hardware") == "hardware-lazyplan"
    assert resolve_learner("paper") == "paper"
    assert set(DESCRIPTIONS) == set(learner_names())


def test_study_help_lists_each_learner_on_one_line_within_80_columns() -> None:
    env = {**os.environ, "COLUMNS": "80", "TERMINAL_WIDTH": "80"}
    out = subprocess.run([sys.executable, "-m", "simulator", "study", "--help"], env=env, capture_output=True,
                         text=True, check=True).stdout
    lines = out.splitlines()
    assert max(len(line) for line in lines) <= 80
    for name in learner_names():
        row = [line for line in lines if line.split()[:1] == [name]]
        assert len(row) == 1, name
        assert DESCRIPTIONS[name] in row[0]
