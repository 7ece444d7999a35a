"""The run pane's learner-restart line and the run's episode count across restarts (groundstation/run/
learner_restarts.py), from the frames a 1.3 and a 1.2 agent send."""

from __future__ import annotations

from groundstation.run.learner_restarts import LearnerRestarts
from protocol import AckResult
from protocol import messages as m


def _beat(episode: int, generation: int) -> m.Heartbeat:
    return m.Heartbeat(episode=episode, generation=generation)


def test_a_1_3_agent_s_restart_names_the_command_and_the_run_counts_on() -> None:
    r = LearnerRestarts()
    r.started_at(2)  # the agent had run 2 episodes before this run
    assert r.received(_beat(2, 1)) is None and r.received(_beat(5, 1)) is None
    r.sent(m.ParamSet(index=-1, value=0.98, name="gamma"))
    assert r.received(m.Ack(cmd_msg_id=m.ParamSet.MSG_ID, cmd_seq=9, result=int(AckResult.ACCEPTED))) is None
    line = r.received(_beat(0, 2))
    assert line is not None and "PARAM_SET gamma" in line and "chapter 2, generation 2" in line
    assert "goes on from 3" in line  # episodes 3, 4 and 5 of the first learner were the run's
    r.received(_beat(4, 2))
    assert r.run_episodes(4) == 7
    assert r.received(_beat(4, 2)) is None  # one line per restart


def test_a_non_learner_parameter_is_not_taken_for_the_cause() -> None:
    r = LearnerRestarts()
    r.received(_beat(1, 1))
    r.sent(m.ParamSet(index=-1, value=0.5, name="target_depth_m"))
    r.received(m.Ack(cmd_msg_id=m.ParamSet.MSG_ID, cmd_seq=3, result=int(AckResult.ACCEPTED)))
    line = r.received(_beat(0, 2))
    assert line is not None and "not through this ground" in line


def test_a_1_2_agent_s_restart_is_inferred_from_its_counter_going_back() -> None:
    r = LearnerRestarts()
    r.received(_beat(4, 0))
    r.received(m.Text(text="model reset"))
    line = r.received(_beat(0, 0))
    assert line is not None and "inferred" in line and 'the agent said "model reset"' in line
    assert r.run_episodes(2) == 6
