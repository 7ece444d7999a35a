"""The check's belief about the simulator's start_at_rest follows the agent, whatever set it.

CI once failed `modes.cmd_stop` on a right agent ("no EPISODE_END aborted after the ACK"): `params.in_learning` had
put start_at_rest back to the value it read before agent.reach set it to 1, the probe still believed 1, so the next
reach sent CMD_START for an episode at rest with the CMD_STOP right behind; the agent recovered first, and the STOP
met RECOVERING while the probe judged it as met in LEARNING. A virtual agent process over a pty, the hardware preset
(whose episodes do not start at rest until told to), at full speed.
"""

from __future__ import annotations

from pathlib import Path

from groundstation.check.agent import reach, restore
from groundstation.check.modes import judge_cell
from groundstation.check.probe import START_AT_REST, Probe, Timeouts
from groundstation.links import make_link
from protocol import Mode
from protocol import messages as m
from tests.groundstation.check_helpers import agent


def test_a_start_at_rest_put_back_behind_reach_is_followed_and_a_stop_in_learning_aborts(tmp_path: Path) -> None:
    with agent(tmp_path, "--pty", "--preset", "hardware", "--seed", "3") as url:
        probe = Probe(make_link(url).open(), timeouts=Timeouts(reply_s=10.0))
        try:
            assert probe.await_program() == ""
            reach(probe, Mode.LEARNING)  # sets start_at_rest = 1: the episode begins at the CMD_START
            assert probe.notes[START_AT_REST] == 1.0
            probe.entered = None
            reach(probe, Mode.IDLE)
            probe.accepted(m.ParamSet(index=-1, value=0.0, name=START_AT_REST), "start_at_rest = 0")
            probe.barrier()
            assert probe.notes[START_AT_REST] == 0.0  # from the PARAM_VALUE that answered the PARAM_SET
            judged = []
            for _ in range(20):
                reach(probe, Mode.LEARNING)
                before, problem = judge_cell(probe, "CMD_STOP", m.Stop, Mode.LEARNING)
                assert problem == "", problem
                judged.append(before)
                if before == Mode.LEARNING:
                    break
            assert Mode.LEARNING in judged, judged
            restore(probe)
        finally:
            probe.close()
