"""The fine step near a hover (issue 43, LearnerConfig.fine_step_deg, fine_reversal_deg) in C against Python, step
by step.

learner.c learner_step_deg is the C twin of learning/acting.py step_size_kernel: the Python environment runs the
fine41 learners on the hardware plant, and the C chain (velocity filter, step size with the reversal, window clamp,
state) given the same measured depths must command the same gear angle at every step. The agent parameters
`fine_step_deg`, `fine_speed_mps` and `fine_reversal_deg` give both agents the learner; and both agents' learning
step (modes.c, modes.py) moves the gear by the fine step (by fine_reversal_deg on a reversal) exactly where the
velocity in their SAMPLE is under fine_speed_mps.
"""

from __future__ import annotations

import ctypes
from collections.abc import Callable
from dataclasses import asdict
from typing import Any

import numpy as np
import pytest

from learning import LearnerConfig, learner_preset
from learning.acting import step_size_kernel
from learning.config import kernel_spec
from protocol import AckResult, FrameEncoder, FrameFlag, Mode, StreamDecoder, messages
from protocol.parameters import param
from simulator.agent.mission import MissionConfig
from simulator.agent.onboard import PythonAgent
from simulator.gym.task import DivingEnv
from simulator.parameters import preset
from simulator.serve.firmware_host import FirmwareAgent, load_library
from tests.firmware.core_build import use_firmware_cache
from tests.firmware.ctl_lib import (
    HARDWARE_BY_PARAMS,
    BothAgents,
    VfilterState,
    build_ctl_library,
    c_config,
    vfilter_gains,
)

FINE = (("fine_step_deg", 0.7), ("fine_speed_mps", 0.016))  # the fine41 learner's (learning/presets.py)
REVERSAL = (("fine_reversal_deg", 1.4),)  # fine41-rev14's
F32_DEG = 1e-3  # the C offset sums f32 steps (0.7f is 0.699999988): ~1e-8 deg per step over a few thousand steps
F32_MPS = 2e-6  # float32 against float64 in the contracting filter (tests/firmware/test_ctl_velocity_filter.py)
ACK = int(FrameFlag.ACK_REQUESTED)


@pytest.fixture(scope="module")
def ctl(tmp_path_factory: pytest.TempPathFactory) -> ctypes.CDLL:
    return build_ctl_library(tmp_path_factory.mktemp("fine"))


@pytest.mark.parametrize("learner", ["fine41", "fine41-v8", "fine41-rev14"])
def test_c_step_follows_python_step_by_step(ctl: ctypes.CDLL, learner: str) -> None:
    """The learner on the hardware plant, random actions (every step size occurs: the plant's, the fine step and for
    fine41-rev14 the reversal step): C's velocity, step and commanded offset follow the Python environment's at
    every step; where the velocity is within float32 rounding of fine_speed_mps the two may choose differently, so C
    takes Python's offset there (counted, and rare)."""
    config = learner_preset(learner)
    params = preset("hardware")
    assert ctl.learner_configure(ctypes.byref(c_config(ctl, config)))
    spec = kernel_spec(config)
    gains = vfilter_gains(config)
    env = DivingEnv(params, config)
    rng = np.random.default_rng(43)
    state = VfilterState()
    window = params.action_window_deg
    obs, _ = env.reset(seed=7)
    ctl.vfilter_start(ctypes.byref(state), float(np.float32(obs[0])), 0.0)
    velocity_c, offset_c = state.v_mps, float(obs[2])
    sizes = dict.fromkeys({config.fine_step_deg, config.fine_reversal_deg or config.fine_step_deg,
                           params.action_step_deg}, 0)
    on_the_edge = 0
    last_action = -1  # the episode's first action is a reversal (simulator/plant/episode.py, modes.c)
    for k in range(4000):
        action = int(rng.integers(2))
        reversal = action != last_action
        last_action = action
        step_c = ctl.learner_step_deg(velocity_c, params.action_step_deg, reversal)
        step_py = step_size_kernel(float(obs[1]), params.action_step_deg, reversal, spec)
        offset_c = min(max(offset_c + (step_c if action == 1 else -step_c), -window), window)
        obs, _, terminated, truncated, info = env.step(action)
        if abs(abs(velocity_c) - config.fine_speed_mps) < F32_MPS:
            on_the_edge += 1
            offset_c = float(obs[2])
        else:
            assert step_c == pytest.approx(step_py, abs=1e-6), k
            assert offset_c == pytest.approx(obs[2], abs=F32_DEG), k
            sizes[step_py] += abs(abs(offset_c) - window) > F32_DEG  # an unclamped step of that size
        velocity_c = ctl.vfilter_update(ctypes.byref(state), ctypes.byref(gains), float(np.float32(obs[0])),
                                        float(np.float32(obs[2])), params.control_period_s)
        assert velocity_c == pytest.approx(obs[1], abs=F32_MPS), k
        if terminated or truncated:  # the filter ran on the ending step too: its bias carries over
            obs, _ = env.reset()
            ctl.vfilter_start(ctypes.byref(state), float(np.float32(obs[0])), 0.0)
            velocity_c, offset_c = state.v_mps, float(obs[2])
            last_action = -1
    assert min(sizes.values()) > 200 and on_the_edge < 10, (sizes, on_the_edge)


def test_c_refuses_a_negative_fine_step_as_python(ctl: ctypes.CDLL) -> None:
    for field_name in ("fine_step_deg", "fine_speed_mps", "fine_reversal_deg"):
        c = c_config(ctl, learner_preset("fine41-rev14"))
        setattr(c, field_name, -0.1)
        assert not ctl.learner_configure(ctypes.byref(c)), field_name
        with pytest.raises(ValueError, match="must not be negative"):
            learner_preset("fine41-rev14", **{field_name: -0.1})
    assert ctl.learner_configure(ctypes.byref(c_config(ctl, learner_preset("fine41-rev14"))))


def test_the_fine_step_parameters_give_both_agents_the_fine_learner(
        tmp_path_factory: pytest.TempPathFactory) -> None:
    """PARAM_SET z_cells = 21, fine_step_deg = 0.7, fine_speed_mps = 0.008 and fine_reversal_deg = 1.4 on top of the
    hardware learner's parameters make both agents' learner the fine21-rev14 preset; fine41's 41 cells do not fit
    the RAM budget (both refuse them with one reason); out of range is refused by both."""
    use_firmware_cache(tmp_path_factory)
    both = BothAgents(load_library())
    fine21_rev14 = (("z_cells", 21), ("fine_step_deg", 0.7), ("fine_speed_mps", 0.008), *REVERSAL)
    for name, value in (*HARDWARE_BY_PARAMS, *fine21_rev14):
        assert both.set(name, value) == (AckResult.ACCEPTED, b""), name
    config = learner_preset("fine21-rev14")
    # The Python agent holds the table's values as f32 (0.016 as 0.01600000075995922).
    assert asdict(both.program.config) == pytest.approx(asdict(config), rel=1e-7)
    both.assert_c_is(config)
    # Each agent words its RAM refusal its own way (tests/firmware/test_shared_learner.py): both name the bytes.
    c_verdict = both.set_c("z_cells", 41)
    assert c_verdict.result == AckResult.BAD_VALUE and b"2871 states needs 63020 B" in c_verdict.reason
    result, reason = both.program.set_param(param("z_cells").index, 41)
    assert result == AckResult.BAD_VALUE and "2871 states need 63020 bytes" in reason, reason
    # SPEC's ranges [0, 20], [0, 0.5] and [0, 20]
    for name, value in (("fine_step_deg", -0.1), ("fine_speed_mps", 0.6), ("fine_reversal_deg", -0.1),
                        ("fine_reversal_deg", 20.5)):
        assert both.set_c(name, value).result == AckResult.BAD_VALUE, name
        assert both.program.set_param(param(name).index, value)[0] == AckResult.BAD_VALUE, name
    both.assert_c_is(config)


class _Ground:
    """One agent (Python or the C host build) on the hardware plant, fed frames in memory, its SAMPLEs kept."""

    def __init__(self, make: Callable[[Callable[[bytes], None]], Any]) -> None:
        self._decoder = StreamDecoder()
        self.samples: list[messages.Sample] = []
        self.acks: list[int] = []
        self.agent = make(self._wrote)
        self._encoder = FrameEncoder(first_seq=1)

    def _wrote(self, wire: bytes) -> None:
        for frame in self._decoder.feed(wire):
            if isinstance(frame.message, messages.Sample):
                self.samples.append(frame.message)
            elif isinstance(frame.message, messages.Ack):
                self.acks.append(frame.message.result)

    def command(self, message: Any) -> None:
        self.agent.receive(self._encoder.encode(message, ACK).wire)
        for _ in range(20):
            self.agent.step()


def _agents(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Callable[[Callable[[bytes], None]], Any]]:
    use_firmware_cache(tmp_path_factory)
    params = preset("hardware")
    return {
        "python": lambda write: PythonAgent(params, LearnerConfig(), MissionConfig(), np.random.default_rng(5), write,
                                            node_id=5, key=None),
        "c": lambda write: FirmwareAgent(params, np.random.default_rng(5), write, node_id=5, key=None, seed=5),
    }


@pytest.mark.parametrize("which", ["python", "c"])
def test_both_agents_step_fine_at_a_hover(tmp_path_factory: pytest.TempPathFactory, which: str) -> None:
    """The agent set to the hardware learner with fine41-rev14's steps learns for 2 000 control steps; every LEARNING
    SAMPLE's command moved, where its velocity is under fine_speed_mps, by fine_reversal_deg if its action reverses
    the SAMPLE's before and by fine_step_deg if not, and by action_step_deg elsewhere (but where the window clamps
    it), each size many times."""
    ground = _Ground(_agents(tmp_path_factory)[which])
    for name, value in (*HARDWARE_BY_PARAMS, *FINE, *REVERSAL):
        ground.command(messages.ParamSet(index=-1, value=float(value), name=name))
    ground.command(messages.StartLearning(max_episodes=0))
    assert set(ground.acks) == {AckResult.ACCEPTED}
    for _ in range(12_000):  # recovery periods are 0.025 s: a few thousand learning steps among them
        ground.agent.step()
    params = preset("hardware")
    fine, reverse, speed = (float(np.float32(value)) for value in (0.7, 1.4, 0.016))
    seen = {fine: 0, reverse: 0, params.action_step_deg: 0}
    for before, after in zip(ground.samples, ground.samples[1:], strict=False):
        if not (before.mode == after.mode == Mode.LEARNING and after.episode == before.episode
                and before.action in (0, 1) and after.action in (0, 1)):
            continue  # also the episode's first action: its SAMPLE's before is not its last action
        moved = abs(after.actuator_cmd_deg - before.actuator_cmd_deg)
        if min(abs(moved - size) for size in seen) > 1e-4:
            continue  # clamped by the window: a smaller move
        slow_step = reverse if after.action != before.action else fine
        expected = slow_step if abs(after.velocity_mps) < speed else params.action_step_deg
        if abs(abs(after.velocity_mps) - speed) > 1e-6:  # the SAMPLE's f32 velocity is the one the step used
            assert moved == pytest.approx(expected, abs=1e-4), (after.sample, after.velocity_mps, moved)
            seen[expected] += 1
    assert min(seen.values()) > 50, seen
