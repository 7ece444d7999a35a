"""What the run pane says of an alarm and the status line of an episode (issue 40): no rounding that contradicts
itself ("depth 1.20 m is past the 1.2 m limit"), and the time held of the success time from the agent's frames."""

from __future__ import annotations

from groundstation.run.alarms import past
from groundstation.session.status_line import AgentStatus, status_line
from protocol import Mode
from protocol import messages as m


def test_a_depth_past_the_limit_never_reads_as_the_limit() -> None:
    assert past(1.2049, 1.2) == "1.205"  # 2 decimals would say 1.20
    assert past(1.2001, 1.2) == "1.2001"
    assert past(1.26, 1.2) == "1.26"  # 2 decimals when they tell


def _sample(t_s: float, mode: Mode, depth_m: float = 0.41) -> m.Sample:
    return m.Sample(t_us=int(t_s * 1e6), sample=0, episode=3, step=0, pressure_pa=0.0, depth_m=depth_m,
                    velocity_mps=0.0, actuator_deg=0.0, actuator_cmd_deg=0.0, reward=0.0, state=0, action=255,
                    mode=int(mode))


def test_the_status_line_holds_the_time_held_of_the_success_time_and_the_target() -> None:
    agent = AgentStatus()
    agent.update(m.Heartbeat(uptime_ms=1000, mode=int(Mode.LEARNING), battery_mv=4150, rx_frames=0, rx_rejects=0,
                             rx_lost=0, log_first_sample=0, log_next_sample=0, episode=3, signing_rejects=0))
    agent.param("success_time_s", 300.0)
    agent.update(m.EpisodeStart(t_us=10_000_000, episode=3, sample=0, start_state=0, depth_m=0.4, velocity_mps=0.0,
                                target_depth_m=0.6000000238418579, z_tol_m=0.1, zdot_tol_mps=0.04, p_explore=0.1))
    agent.update(_sample(222.4, Mode.LEARNING))
    line = status_line(agent, {"rtt_median_ms": 12.0, "loss_fraction": 0.0}, alarm="ALARM depth")
    assert line == ("LEARNING | episode 3 | successes unknown (no episode ended while watching) | held 212/300 s | "
                    "target 0.60 m | depth 0.41 m | 4.15 V | rtt 12 ms, loss 0.0% | ALARM depth")
    agent.update(_sample(223.0, Mode.RECOVERING))  # recovering: nothing is held
    assert "held" not in status_line(agent, {})


def test_a_dump_in_json_has_the_agents_float32_without_noise() -> None:
    import struct

    from groundstation.session.dumps import Dump
    from protocol import DumpKind

    dump = Dump(7, DumpKind.VALUES, 3, struct.pack("<3f", 0.4, -3.2, 8.6))
    assert dump.values() != [0.4, -3.2, 8.6]  # widened: 0.4000000059604645, ...
    assert dump.as_dict()["values"] == [0.4, -3.2, 8.6]
