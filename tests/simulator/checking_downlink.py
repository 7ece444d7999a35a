"""A test downlink for the on-board program: keeps every frame, checks each SAMPLE against the program's state."""

from __future__ import annotations

from protocol import messages
from protocol.registry import Message
from simulator.agent.program import OnboardProgram


class CheckingDownlink:
    """Keeps every frame's payload and checks each SAMPLE against the message built from the program's state."""

    def __init__(self) -> None:
        self.program: OnboardProgram | None = None
        self.payloads: list[bytes] = []
        self.samples = 0

    def log_frame(self, message: Message, sample: int, is_sample: bool) -> None:
        self.payloads.append(message.pack())

    def log_payload(self, msg_id: int, payload: bytes, sample: int, is_sample: bool) -> None:
        assert self.program is not None and msg_id == messages.Sample.MSG_ID
        prog, hw = self.program, self.program.hw
        sent = messages.Sample.unpack(payload)
        built = messages.Sample(
            t_us=hw.t_us, sample=sample, episode=prog.episode, step=sent.step, pressure_pa=prog.pressure_pa,
            depth_m=prog.depth_m, velocity_mps=prog.velocity_mps, actuator_deg=hw.actuator_deg,
            actuator_cmd_deg=hw.actuator_cmd_deg, reward=sent.reward, state=sent.state, action=sent.action,
            mode=int(prog.mode),
        )
        assert payload == built.pack()
        self.payloads.append(payload)
        self.samples += 1

    def send(self, message: Message) -> None:
        self.payloads.append(message.pack())

    def episode_dumps(self) -> None:
        pass

    def link_silence_s(self) -> float:
        return 0.0

    def model_changed(self) -> None:
        pass
