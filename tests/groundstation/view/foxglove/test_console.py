"""Foxglove as a console (issue 40 item 3), seen by a client speaking Foxglove's WebSocket protocol against the real
server: the agent's log and the run's events on /log as foxglove.Log, log times on the agent's clock (a batch's
SAMPLEs never share one), the parameters' metadata, the raw frames advertised as every recorded topic is."""

from __future__ import annotations

import json

from groundstation.session.events import EventKind, LinkEvent, Received, Sent
from groundstation.view.foxglove.console import LOG_TOPIC, PARAMETER_INFO_TOPIC
from groundstation.view.foxglove.live import FoxgloveLive
from protocol import Frame, FrameEncoder
from protocol import messages as m
from protocol.frame import build_inner
from tests.groundstation.foxglove_client import FoxgloveClient
from tests.groundstation.synthetic_agent import START_NS, generate

BATCH = 10  # SAMPLEs that arrive in one read, as at speed: one arrival time for all


def _batched(frames: list[Received]) -> list[Received]:
    """The agent's frames as a session delivers them at speed: each SAMPLE with its agent time mapped to the host
    clock, arriving BATCH at a time with the batch's last arrival time."""
    out: list[Received] = []
    batch: list[Received] = []
    for received in frames:
        msg = received.frame.message
        if isinstance(msg, m.Sample):
            batch.append(received._replace(agent_time_ns=START_NS + msg.t_us * 1000))
            if len(batch) == BATCH:
                out += [r._replace(host_time_ns=batch[-1].host_time_ns + 5_000_000) for r in batch]
                batch = []
        else:
            out.append(received)
    return out


def _param_value(name: str, value: float) -> Received:
    msg = m.ParamValue(index=0, count=37, param_type=5, value=value, minimum=0.05, maximum=2.5, name=name)
    inner = build_inner(0, 1, msg.MSG_ID, msg.pack())
    return Received(Frame(0, 1, msg.MSG_ID, msg, inner), START_NS, None, False)


def test_log_panel_agent_time_parameter_metadata_and_raw_frames() -> None:
    live = FoxgloveLive(0, "test")
    channels = live.channels
    frames = _batched(generate(duration_s=30.0, seed=5).frames)
    try:
        # the first of each kind advertises its channel
        for received in frames[:40]:
            channels.on_received(received)
        channels.on_received(_param_value("target_depth_m", 0.4000000059604645))
        channels.on_event(LinkEvent(EventKind.ALARM, START_NS + 1, "depth 1.31 m is past the 1.2 m limit",
                                    {"alarm": "depth"}))
        pause = m.Pause()
        channels.on_sent(Sent(7, pause, FrameEncoder().encode(pause).wire, START_NS + 3))
        with FoxgloveClient.connected(live.port) as fox:
            wanted = {"/agent/SAMPLE", LOG_TOPIC, PARAMETER_INFO_TOPIC, "/raw/rx", "/raw/tx", "/ground/CMD_PAUSE"}
            assert fox.pump(lambda: wanted <= set(fox.channels), 5), sorted(fox.channels)
            assert fox.channels[LOG_TOPIC]["schemaName"] == "foxglove.Log"
            samples, log, info = (fox.subscribe(topic) for topic in ("/agent/SAMPLE", LOG_TOPIC,
                                                                      PARAMETER_INFO_TOPIC))
            assert fox.pump(lambda: bool(fox.messages.get(info)) and bool(fox.messages.get(log)), 5)
            for received in frames[40:]:
                channels.on_received(received)
            channels.on_event(LinkEvent(EventKind.MARKER, START_NS + 2_000_000_000, "tapped", {"text": "tapped"}))
            sent = [r for r in frames if isinstance(r.frame.message, m.Sample)]
            assert fox.pump(lambda: len(fox.messages.get(samples, [])) == len(sent), 10), len(fox.messages[samples])
            assert fox.pump(lambda: any(b"tapped" in body for body in fox.messages[log]), 5)
            raw = fox.channels["/raw/tx"]  # the recording's raw frames, in its own encoding
        # every SAMPLE stamped with its agent time: a batch's ten are ten times, one per control step
        assert fox.log_times[samples] == [START_NS + r.frame.message.t_us * 1000 for r in sent]
        assert len(set(fox.log_times[samples])) == len(sent)
        lines = [json.loads(body) for body in fox.messages[log]]
        alarm = next(line for line in lines if line["message"].startswith("alarm: "))
        assert (alarm["level"], alarm["name"]) == (4, "dive")  # ERROR, from the run
        agent = next(line for line in lines if line["name"] == "agent")
        assert agent["message"].startswith("episode ") and agent["level"] == 2  # the agent's TEXT, INFO
        assert {"sec", "nsec"} <= set(agent["timestamp"])
        [target] = [json.loads(body) for body in fox.messages[info]]
        assert target["unit"] == "m" and target["description"].startswith("target depth")
        assert (target["minimum"], target["maximum"], target["resets_learning"]) == (0.05, 2.5, False)
        assert target["refused_in"] == ["LEARNING"]
        assert (raw["encoding"], raw["schemaName"]) == ("diving-agent-frame-v1", "diving_agent.frame")
    finally:
        live.close()
