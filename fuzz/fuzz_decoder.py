"""atheris harness for long fuzzing runs of the decoder and the signing agent's receive path (not run in CI).

    pip install atheris && python fuzz/fuzz_decoder.py -max_total_time=3600 [corpus_dir]
"""

from __future__ import annotations

import sys

import numpy as np

from learning import LearnerConfig
from protocol import FrameEncoder, Mode, Signer, StreamDecoder, messages
from protocol.frame import MAX_CHUNK
from simulator.agent.hardware import SimulatedHardware
from simulator.agent.link import AgentLink
from simulator.agent.log_ring import LogRing
from simulator.agent.mission import MissionConfig
from simulator.agent.program import OnboardProgram
from simulator.parameters import preset

KEY = bytes(range(32))
_params = preset("hardware")
_rng = np.random.default_rng(0)
_out = bytearray()
_link = AgentLink(_out.extend, node_id=1, ring=LogRing(64 * 1024), key=KEY)
_program = OnboardProgram(_params, LearnerConfig(), MissionConfig(), SimulatedHardware(_params, _rng), _rng, _link)
_link.attach(_program)
_link.on_connect()
_signed = FrameEncoder(signer=Signer(KEY, 1))


def one_input(data: bytes) -> None:
    """Any bytes: the decoder must not raise or hold more than one chunk; the agent must keep its state valid."""
    decoder = StreamDecoder()
    decoder.feed(data)
    assert decoder.buffered_bytes <= MAX_CHUNK
    _link.receive(data)
    _program.step()
    _link.tick()
    assert _program.mode in set(Mode)
    _out.clear()
    _link.receive(b"\x00" + _signed.encode(messages.Timesync(origin_us=1)).wire)
    assert _out, "the agent still answers"


def main() -> None:
    import atheris  # only for long runs; not a project dependency

    atheris.Setup(sys.argv, one_input)
    atheris.Fuzz()


if __name__ == "__main__":
    main()
