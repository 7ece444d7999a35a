"""The C firmware's host build switched to the shared-model learner by PARAM_SET, as a ground station would:
`dive run` learns with shared-bins13-diff4 (S = 1301, accepted within the RAM budget of SPEC.md s. 13), then
its POLICY and its live-rendered Q_VALUES come back by `dive dump`."""

from __future__ import annotations

import json
from collections.abc import Iterator
from pathlib import Path

import pytest
from typer.testing import CliRunner

from groundstation.cli.app import app
from groundstation.recording.info import summarize
from tests.firmware.core_build import c_agent, use_firmware_cache

pytestmark = pytest.mark.slow
# shared_model first, so that every learner on the way fits the budget (act_bins = 13 alone is refused).
SHARED_BINS13_DIFF4 = ("shared_model=1", "in_place_sweeps=1", "p_explore_start=0", "vel_diff_steps=4",
                       "act_bins=13")
STATES = 10 * 10 * 13 + 1


@pytest.fixture(scope="module")
def agent(tmp_path_factory: pytest.TempPathFactory) -> Iterator[str]:
    use_firmware_cache(tmp_path_factory)
    with c_agent("--tcp", "127.0.0.1:0", seed=3) as address:
        assert address.startswith("tcp://127.0.0.1:"), address
        yield address


def test_shared_learner_runs_and_dumps(agent: str, tmp_path: Path) -> None:
    params = [arg for item in SHARED_BINS13_DIFF4 for arg in ("--param", item)]
    result = CliRunner().invoke(app, ["run", agent, "--episodes", "3", "--success-time", "5", "--viewer", "none",
                                      "--out", str(tmp_path), *params])
    assert result.exit_code == 0, result.output
    summary = summarize(Path(result.stdout.strip().splitlines()[-1]))
    assert summary.complete and len(summary.episodes) >= 3 and summary.samples_missing == 0
    policy = CliRunner().invoke(app, ["dump", agent, "--kind", "policy"])
    assert policy.exit_code == 0, policy.output
    actions = json.loads(policy.stdout)["values"]
    assert len(actions) == STATES
    tried = [a for a in actions if a != 255]
    assert tried and set(tried) <= {0, 1} and actions[-1] == 255  # some states left, the terminal never
    q = CliRunner().invoke(app, ["dump", agent, "--kind", "q"])
    assert q.exit_code == 0, q.output
    flat = json.loads(q.stdout)["values"]  # q[S][2], flattened
    assert len(flat) == 2 * STATES
    # Q of a state never left: both types untried, the optimistic 0; of a tried one: a reward was seen.
    assert any(v != 0.0 for v in flat) and flat[-2:] == [0.0, 0.0]
