"""A real recording without a socket: the virtual agent's on-board program (Python, or the C firmware's host build)
over its simulated plant, stepped in-process, its wire bytes decoded and handed to the real recorder as a session
would. Minutes of agent time in well under a second: real plant data for the export tests."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from groundstation.recording.recorder import Recorder, RecorderConfig
from groundstation.session.events import EventKind, LinkEvent, Received
from groundstation.session.hello import ground_hello
from learning import learner_preset
from protocol import Frame, FrameEncoder, StreamDecoder, definitions_hash
from protocol import messages as m
from protocol.frame import build_inner
from simulator.agent.mission import MissionConfig
from simulator.agent.onboard import OnboardAgent, PythonAgent
from simulator.parameters import preset

START_NS = 1_700_000_000_000_000_000  # host clock at agent time 0


def _agent(preset_name: str, firmware: str, seed: int, write: list[bytes]) -> OnboardAgent:
    plant, rng = preset(preset_name), np.random.default_rng(seed)
    if firmware == "c":
        from simulator.serve.firmware_host import FirmwareAgent  # builds (once, cached) or loads the C library

        return FirmwareAgent(plant, rng, write.append, 0x5100_0000 | seed, None, seed, wall_link_clock=False)
    return PythonAgent(plant, learner_preset("paper"), MissionConfig(), rng, write.append, 0x5100_0000 | seed, None)


def record_onboard(path: Path, preset_name: str, firmware: str = "python", seed: int = 1, episodes: int = 3,
                   max_steps: int = 200_000, until_bytes: int = 0, split_bytes: int = 0, dumps: bool = False,
                   restart_after: int = 0, as_1_2: bool = False, restart_text: bool = True) -> list[Path]:
    """Record the agent learning until `episodes` episodes ended (or `max_steps` steps, or `until_bytes` on disk)
    into `path` (its parts with `split_bytes`: the recorder's split option); with `dumps`, a VALUES and POLICY dump
    after each episode, as `dive run` asks for. The files written.

    restart_after: after that many episodes, pause, set a learner parameter (gamma: the learner restarts, SPEC 1.3
    s. 6) and start again, as on a tank day. as_1_2: recorded as a 1.2 agent would send it (its 1.2 table hash, no
    generation: 0); without restart_text its TEXT about the restart is lost too.
    """
    wire: list[bytes] = []
    agent = _agent(preset_name, firmware, seed, wire)
    agent.link_up()
    ground = FrameEncoder()
    agent.receive(ground.encode(ground_hello(0x600D, 1)).wire)
    agent.receive(ground.encode(m.ParamListRequest()).wire)
    if dumps:
        agent.receive(ground.encode(m.ParamSet(index=-1, value=1.0, name="dump_each_episode")).wire)
    agent.receive(ground.encode(m.StartLearning(max_episodes=0)).wire)
    options = {"sim_preset": preset_name, "sim_firmware": firmware, "sim_seed": str(seed), "sim_speed": "max"}
    url = f"sim://?preset={preset_name}&firmware={firmware}&seed={seed}"
    recorder = Recorder(RecorderConfig(path=path, split_bytes=split_bytes), session_info={"url": url, **options})
    decoder = StreamDecoder()
    parameters: dict[str, float] = {}
    ended = steps = 0
    try:
        recorder.on_event(LinkEvent(EventKind.CONNECTED, START_NS, url))
        while ended < episodes and steps < max_steps:
            if restart_after and ended == restart_after:
                restart_after = 0
                for command in (m.Pause(), m.ParamSet(index=-1, value=0.98, name="gamma")):
                    agent.receive(ground.encode(command).wire)
                    if agent.work_after_ack:
                        agent.finish_command()
                agent.receive(ground.encode(m.StartLearning(max_episodes=0)).wire)
            agent.step()
            steps += 1
            if until_bytes and steps % 4096 == 0 and sum(p.stat().st_size for p in recorder.paths) >= until_bytes:
                break
            data, wire[:] = b"".join(wire), []
            for frame in decoder.feed(data):
                message = frame.message
                if isinstance(message, m.ParamValue):
                    parameters[message.name] = message.value
                    if len(parameters) == message.count:
                        recorder.set_parameters(parameters)
                ended += isinstance(message, m.EpisodeEnd)
                if as_1_2:
                    frame = _as_1_2(frame, restart_text)
                    if frame is None:
                        continue
                host_ns = START_NS + agent.t_us * 1000
                recorder.on_received(Received(frame, host_ns, host_ns, False))
    finally:
        recorder.close()
    return recorder.paths


def _as_1_2(frame: Frame, restart_text: bool) -> Frame | None:
    """The frame as a 1.2 agent sends it: no generation (0), its table's hash; None for a lost restart TEXT."""
    message = frame.message
    if isinstance(message, m.Text) and "restarted" in message.text and not restart_text:
        return None
    values = message.to_dict()
    if "generation" not in values:
        return frame
    values["generation"] = 0
    if isinstance(message, m.Hello):
        values["definitions_hash"] = definitions_hash(before_1_3=True)
    old = type(message).from_dict(values)
    inner = build_inner(frame.flags, frame.seq, frame.msg_id, old.pack())
    return Frame(frame.flags, frame.seq, frame.msg_id, old, inner)
