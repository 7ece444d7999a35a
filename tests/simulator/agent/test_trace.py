"""The virtual agent sends the same wire bytes and logs the same records as before its fast paths, seed for seed.

The fixture was captured from main (one step and one link tick per call), never from this branch: first at aa759ad,
again at 1e82738 and at c766169, whose SPEC 1.1 changes altered the wire themselves (main's own code gives the new
bytes; the speed-ups give the same), and after the `vel_penalty` parameter was appended (34 parameters): the wire
before and after differs in one frame only, the PARAM_VALUE's `count` (33 -> 34) and its CRC; the log is unchanged.
Likewise after `velocity_filter` (35 parameters, regenerated with `python -m tests.simulator.agent_trace`): only
the wire's hash changed, its length and frames not; and after `plan_stable_sweeps` and `plan_loose_tol`
(37 parameters, the same way): again only the wire's hash; and after `fine_step_deg` and `fine_speed_mps`
(39 parameters, the same way): again only the wire's hash, the log unchanged; and after `fine_reversal_deg` (40
parameters): the same; and after `plan_growth` (41 parameters): the same.
"""

from __future__ import annotations

import json

import pytest

from protocol import compiled
from tests.simulator import agent_trace

EXPECTED = {(t["preset"], t["seed"]): t for t in json.loads(agent_trace.FIXTURE.read_text())}


@pytest.mark.parametrize(("preset_name", "seed"), sorted(EXPECTED))
def test_the_served_agent_sends_and_logs_the_bytes_of_the_fixture(preset_name: str, seed: int) -> None:
    assert compiled.wait(300)  # the compiled frame writer in use, not the stdlib one it falls back to while loading
    assert agent_trace.run(preset_name, seed) == EXPECTED[preset_name, seed]
