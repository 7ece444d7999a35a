"""Parameters that never surprise (issue 27 item 2): a real `dive run` on the virtual agent, `dive params` through
its hub as processes. The same value is not sent; a learner restart needs --reset-model; a refusal names each
parameter and the mode; the listing says what each parameter is and whether changing it resets learning."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from groundstation.mcap_io import read_recording
from protocol.parameters import PARAM_COUNT
from tests.groundstation.hub_helpers import SIM, dive, one_line_failure, running, until_mode

pytestmark = pytest.mark.slow


def test_params_console_through_the_hub(tmp_path: Path) -> None:
    runtime = tmp_path / "runtime"
    saved = tmp_path / "agent.toml"
    with running(runtime, SIM, tmp_path / "rec", "--success-time", "5", start_timeout_s=120) as run:
        assert until_mode(runtime, {"LEARNING"}) == "LEARNING"
        listing = dive(runtime, "params")
        assert listing.returncode == 0, listing.stderr
        lines = [line for line in listing.stdout.splitlines() if line.strip()]
        assert len(lines) == PARAM_COUNT
        [gamma_line] = [line for line in lines if " gamma " in line]
        assert "[0 .. 0.999]" in gamma_line and "resets learning" in gamma_line and "discount factor" in gamma_line
        [target_line] = [line for line in lines if " target_depth_m " in line]
        assert re.search(r"0\.4 m\s+\[0\.05 \.\. 2\.5\]", target_line) and "resets learning" not in target_line

        # the value it has: not sent, so neither refused while learning nor a restart
        same = dive(runtime, "params", "set", "gamma", "0.99")
        assert same.returncode == 0 and "gamma = 0.99 (unchanged, not sent)" in same.stdout, same.stderr
        assert dive(runtime, "params", "save", str(saved)).returncode == 0
        diff = dive(runtime, "params", "diff", str(saved))
        assert diff.returncode == 0 and f"0 of {PARAM_COUNT} differ" in diff.stdout, diff.stdout
        loaded = dive(runtime, "params", "load", str(saved))  # while learning: nothing differs, nothing is sent
        assert loaded.returncode == 0, loaded.stderr
        assert loaded.stdout.splitlines() == [f"{PARAM_COUNT} of {PARAM_COUNT} unchanged, not sent"], loaded.stdout

        # a real change while learning: refused before anything is sent, naming the parameter and the mode
        one_line_failure(dive(runtime, "params", "set", "gamma", "0.98"),
                          "not allowed while the agent is LEARNING: gamma; pause first (dive pause)")
        changed = saved.read_text().replace("gamma = 0.99", "gamma = 0.98").replace("z_tol_m = 0.1", "z_tol_m = 0.12")
        saved.write_text(changed)
        diff = dive(runtime, "params", "diff", str(saved))
        assert diff.returncode == 1  # as diff(1): the file differs
        assert f"2 of {PARAM_COUNT} differ; loading it: changing z_tol_m, gamma restarts the learner and changes " \
               "the state grid" in diff.stdout, diff.stdout
        # confirmed, but the agent is learning: one line names both parameters, the mode and what to do
        one_line_failure(dive(runtime, "params", "load", str(saved), "--reset-model"),
                          "not allowed while the agent is LEARNING: z_tol_m, gamma; pause first (dive pause)")
        assert dive(runtime, "pause").returncode == 0
        # paused: allowed, but it restarts the learner, so not without --reset-model (not on a terminal)
        one_line_failure(dive(runtime, "params", "load", str(saved)),
                          "changing z_tol_m, gamma restarts the learner and changes the state grid: it forgets "
                          "everything it learned: add --reset-model", code=2)
        done = dive(runtime, "params", "load", str(saved), "--reset-model")
        assert done.returncode == 0, done.stderr
        assert "gamma = 0.98" in done.stdout and "z_tol_m = 0.12" in done.stdout
        assert f"{PARAM_COUNT - 2} of {PARAM_COUNT} unchanged, not sent" in done.stdout
        assert dive(runtime, "resume").returncode == 0
    run.communicate()
    [recording] = sorted((tmp_path / "rec").glob("*.mcap"))
    contents = read_recording(recording, {"/ground/PARAM_SET", "/agent/TEXT"})
    sets = [m.json()["name"] for m in contents.messages if m.topic == "/ground/PARAM_SET"]
    assert sets == ["success_time_s", "dump_each_episode", "z_tol_m", "gamma"]  # the run's, then the two that differ
    restarts = [m.json()["text"] for m in contents.messages if m.topic == "/agent/TEXT" and "restarted" in
                m.json()["text"]]
    assert len(restarts) == 2, restarts
