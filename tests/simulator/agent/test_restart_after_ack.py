"""A PARAM_SET that restarts the learner is ACKed before the restart runs (SPEC s. 5: the ACK comes before anything
the command causes): a new learner compiles its kernels on first use, seconds on a cold cache or a loaded machine,
and the ground's ACK must not wait for that (the check soak's 'PARAM_SET shared_model=1.0: no ACK within 10 s')."""

from __future__ import annotations

import numpy as np

from learning import learner_preset
from protocol import AckResult, FrameEncoder, FrameFlag, StreamDecoder, messages
from simulator.agent.mission import MissionConfig
from simulator.agent.onboard import PythonAgent
from simulator.parameters import preset


def test_the_ack_leaves_before_the_learner_restarts() -> None:
    decoder, received = StreamDecoder(), []
    agent = PythonAgent(preset("paper"), learner_preset("paper"), MissionConfig(), np.random.default_rng(1),
                        lambda wire: received.extend(decoder.feed(wire)), node_id=0x51000001, key=None)
    old_learner = agent.program.learner
    ground = FrameEncoder(first_seq=1)
    restart = messages.ParamSet(index=-1, name="shared_model", value=1.0)
    agent.receive(ground.encode(restart, FrameFlag.ACK_REQUESTED).wire)
    acks = [f.message for f in received if isinstance(f.message, messages.Ack)]
    assert [a.result for a in acks] == [AckResult.ACCEPTED]
    assert agent.program.learner is old_learner  # the ACK is out; the restart has not run yet
    assert agent.program.config.shared_model  # but the agent already answers with the new configuration

    assert agent.work_after_ack  # what the server (serve/loop.py) waits on: it lets the ACK leave first
    agent.finish_command()
    assert not agent.work_after_ack
    assert agent.program.learner is not old_learner and agent.program.learner.config.shared_model
    texts = [f.message.text for f in received if isinstance(f.message, messages.Text)]
    assert "shared_model changed: learner restarted, generation 2" in texts  # SPEC 1.3: the new generation
