"""Foxglove live with controls (issue 27 item 6): a real `dive run --foxglove` on the virtual agent, and a client
speaking Foxglove's WebSocket protocol as the Foxglove app does: channels, parameters and services."""

from __future__ import annotations

import json
import os
import re
import socket
import struct
import subprocess
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import pytest

from groundstation.mcap_io import read_recording
from groundstation.recording.recorder import message_schema
from groundstation.view.foxglove.images import POLICY_TOPIC, VALUE_TOPIC
from groundstation.view.foxglove.services import REQUESTS
from groundstation.view.options import with_flag_value
from protocol import FrameFlag
from protocol import messages as m
from protocol.parameters import PARAM_COUNT
from protocol.registry import message_classes
from tests.groundstation.foxglove_client import SUBPROTOCOL, FoxgloveClient
from tests.groundstation.hub_helpers import DIVE, dive_env, interrupt, one_line_failure

FAST_SIM = "sim://?speed=max&seed=4"


def start_dive(tmp_path: Path, *args: str) -> subprocess.Popen[str]:
    """`dive ARGS --foxglove 0`: it binds and prints its address first."""
    return subprocess.Popen([*DIVE, *args, "--foxglove", "0"], env=dive_env(tmp_path / "runtime"),
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


@contextmanager
def foxglove_client(proc: subprocess.Popen[str]) -> Iterator[FoxgloveClient]:
    """A client connected to the port `proc` printed; SIGINT to `proc` when the block ends."""
    try:
        assert proc.stderr is not None
        first = proc.stderr.readline()  # the address, before the virtual agent is started
        found = re.search(r"Foxglove: ws://127\.0\.0\.1:(\d+)", first)
        assert found is not None, first + proc.stderr.read()
        with FoxgloveClient.connected(int(found.group(1))) as client:
            yield client
    finally:
        interrupt(proc)


def write_key(path: Path) -> Path:
    path.write_text(os.urandom(32).hex() + "\n")
    path.chmod(0o600)
    return path


@pytest.mark.slow
def test_foxglove_watches_sets_and_commands_a_running_keyed_run(tmp_path: Path) -> None:
    """A keyed run (the agent refuses unsigned commands): Foxglove's parameters and services reach it signed with
    the run's key, and `dive view --foxglove --key-file` beside it signs its own (the agent refuses even a
    PARAM_LIST unsigned, so its Parameters panel filled is the proof)."""
    key = write_key(tmp_path / "agent.key")
    # low_batt_v at its floor: at speed max the battery would end the run on its own before the test's Ctrl-C
    proc = start_dive(tmp_path, "run", f"{FAST_SIM}&key_file={key}", "--key-file", str(key),
                      "--param", "low_batt_v=3.0", "--out", str(tmp_path / "rec"))
    with foxglove_client(proc) as fox:
        assert fox.ws.subprotocol == SUBPROTOCOL
        # the server advertises its channels once the run's agent is up (a first start compiles the simulator)
        assert fox.pump(lambda: "/agent/SAMPLE" in fox.channels and "surface" in fox.services, 120), fox.channels
        assert {"parameters", "services"} <= set(fox.server_info["capabilities"])
        sample = fox.channels["/agent/SAMPLE"]  # the recording's topic, schema name and JSON schema
        assert (sample["encoding"], sample["schemaName"], sample["schemaEncoding"]) == \
            ("json", "diving_agent.SAMPLE", "jsonschema")
        assert json.loads(sample["schema"]) == message_schema(m.Sample)
        samples = fox.subscribe("/agent/SAMPLE")
        assert fox.pump(lambda: "/agent/HEARTBEAT" in fox.channels, 5)
        beats = fox.subscribe("/agent/HEARTBEAT")
        assert fox.pump(lambda: len(fox.messages.get(samples, [])) >= 5, 10)
        assert {"depth_m", "mode", "_seq"} <= set(json.loads(fox.messages[samples][0]))
        # at --speed max the SAMPLEs come in batches: each has a log time of its own, in the agent's order
        stamps = fox.log_times[samples]
        assert len(set(stamps)) == len(stamps) and stamps == sorted(stamps), stamps[:20]
        assert set(fox.services) == {"surface", "hover", "start", "stop", "pause", "resume", "target", "mark", "dump",
                                     "ack"}

        # the Parameters panel: the agent's table; the value it already has changes nothing
        table = {p["name"]: p["value"] for p in fox.get_parameters([])}
        assert len(table) == PARAM_COUNT and table["gamma"] == 0.99 and table["target_depth_m"] == 0.4
        assert fox.set_parameters({"gamma": 0.99}) == [{"name": "gamma", "type": "float64", "value": 0.99}]
        # a learner parameter while learning: refused by the ground, naming it and the mode, as `dive params set`
        assert fox.set_parameters({"gamma": 0.9})[0]["value"] == 0.99
        assert fox.pump(lambda: any("not allowed while the agent is" in s["message"] and "gamma" in s["message"]
                                    for s in fox.statuses), 3), fox.statuses

        # the controls: the agent's ACK and the mode it ends in, a refusal with what to do instead
        paused = fox.call("pause")
        assert (paused["accepted"], paused["result"], paused["mode"]) == (True, "ACCEPTED", "PAUSED"), paused
        moved = fox.call("target", {"depth_m": 0.5})  # another depth while paused
        assert (moved["accepted"], moved["command"], moved["mode"]) == (True, "CMD_SET_TARGET", "PAUSED"), moved
        resumed = fox.call("resume")
        assert resumed["accepted"] and resumed["mode"] in ("LEARNING", "RECOVERING"), resumed
        hover = fox.call("hover", {"depth_m": 0.3})
        assert (hover["accepted"], hover["result"]) == (False, "NOT_ALLOWED_IN_MODE"), hover
        assert "surface first: dive surface" in hover["message"]
        assert "depth_m" in fox.call("target", {"depth_m": "deep"})["failure"]  # a bad request: a failed call
        policy = fox.subscribe("/policy/image")
        dumped = fox.call("dump", {"kind": "policy"})
        assert dumped["accepted"] and "policy of episode" in dumped["message"], dumped
        assert fox.pump(lambda: bool(fox.messages.get(policy)), 60)  # drawn as a foxglove.RawImage
        assert fox.channels["/policy/image"]["schemaName"] == "foxglove.RawImage"
        assert fox.call("mark", {"text": "from foxglove"})["accepted"]
        acked = fox.call("ack")  # the run's alarms, as dive ack: the answer says what was acknowledged
        assert acked["accepted"] and acked["message"].startswith(("alarms acknowledged by foxglove",
                                                                  "no alarm to acknowledge (foxglove)")), acked
        # the run's own session publishes: its marker event (the hub marks the run's session, not Foxglove's)
        assert fox.pump(lambda: "/marker" in fox.channels, 3), sorted(fox.channels)
        assert "exceeds" in fox.call("mark", {"text": "x" * 100_000})["failure"]  # longer than a frame holds
        surfaced = fox.call("surface")
        assert surfaced["accepted"] and surfaced["mode"] in ("SURFACING", "IDLE"), surfaced
        view = start_dive(tmp_path, "view", "--key-file", str(key))  # after an episode ended: looked at below

        # at the surface a learner restart is allowed, once confirmed by setting the same value again
        assert fox.pump(lambda: bool(fox.messages.get(beats)) and json.loads(fox.messages[beats][-1])["mode"] == 0,
                        120)  # IDLE
        assert fox.set_parameters({"gamma": 0.9})[0]["value"] == 0.99
        assert fox.pump(lambda: any("set the same value again" in s["message"] for s in fox.statuses), 3)
        assert fox.set_parameters({"gamma": 0.9})[0]["value"] == pytest.approx(0.9)
        started = fox.call("start")  # handed back to the run, which learns on
        assert started["accepted"] and started["mode"] in ("LEARNING", "RECOVERING"), started

        # a client that connects late is sent, on each channel it subscribes to and to it alone, what it missed:
        # the episodes from the first, the last minutes of samples
        seen = len(fox.messages[samples])
        seen_sample = json.loads(fox.messages[samples][-1])["sample"]
        with FoxgloveClient.connected(fox.ws.remote_address[1]) as late:
            assert late.pump(lambda: {"/agent/EPISODE_END", "/agent/SAMPLE"} <= set(late.channels), 5)
            ends, late_samples = late.subscribe("/agent/EPISODE_END"), late.subscribe("/agent/SAMPLE")
            assert late.pump(lambda: bool(late.messages.get(ends)) and any(
                json.loads(body)["sample"] < seen_sample for body in late.messages.get(late_samples, [])), 5)
            late_episodes = [json.loads(body)["episode"] for body in late.messages[ends]]
        fox.pump(lambda: False, 0.3)  # what reached the first client meanwhile: live samples only, none replayed
        assert all(json.loads(body)["sample"] > seen_sample for body in fox.messages[samples][seen:])

        # the view's own server, attached to the run's hub after its first episode: the same channels, the agent's
        # parameters, and the run's history, which the view asks the hub for and keeps for its Foxglove clients
        with foxglove_client(view) as beside:
            assert beside.pump(lambda: {"/agent/SAMPLE", "/agent/EPISODE_END"} <= set(beside.channels) and
                               "pause" in beside.services, 20)
            assert {p["name"]: p["value"] for p in beside.get_parameters(["gamma"])} == {"gamma": pytest.approx(0.9)}
            view_ends = beside.subscribe("/agent/EPISODE_END")
            assert beside.pump(lambda: any(json.loads(body)["episode"] == late_episodes[0]  # the run's first
                                           for body in beside.messages.get(view_ends, [])), 5)
        assert view.wait(10) == 130
    _, err = proc.communicate()
    assert proc.returncode == 130, err
    assert "the operator paused learning" in err and "took over (CMD_SURFACE" in err, err
    assert err.count("handed the agent back") == 2, err  # the resume and the start
    [recording] = sorted((tmp_path / "rec").glob("*.mcap"))
    sent = read_recording(recording, {"/ground/PARAM_SET", "/ground/CMD_PAUSE", "/ground/CMD_SET_TARGET",
                                      "/marker"}).messages
    gamma_sets = [msg.json()["value"] for msg in sent
                  if msg.topic == "/ground/PARAM_SET" and msg.json()["name"] == "gamma"]
    first_episodes = [msg.json()["episode"] for msg in read_recording(recording, {"/agent/EPISODE_END"}).messages]
    assert late_episodes[:len(first_episodes)] == first_episodes[:len(late_episodes)]  # from the run's first on
    assert gamma_sets == [pytest.approx(0.9)]  # the equal value, the refused and the unconfirmed sets: never sent
    assert [msg.json()["text"] for msg in sent if msg.topic == "/marker"] == ["from foxglove"]
    assert [bool(msg.json()["_flags"] & FrameFlag.SIGNED) for msg in sent if msg.topic == "/ground/CMD_PAUSE"] == \
        [True]  # Foxglove's pause, signed
    assert all(msg.json()["_flags"] & FrameFlag.SIGNED for msg in sent if msg.topic != "/marker")
    assert [msg.json()["target_depth_m"] for msg in sent if msg.topic == "/ground/CMD_SET_TARGET"] == \
        [pytest.approx(0.5)]


def test_a_foxglove_port_in_use_is_one_line_before_the_agent_is_started(tmp_path: Path) -> None:
    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen()
        port = taken.getsockname()[1]
        began = time.monotonic()
        done = subprocess.run([*DIVE, "run", FAST_SIM, "--out", str(tmp_path / "rec"), "--foxglove", str(port)],
                              env=dive_env(tmp_path / "runtime"), capture_output=True, text=True, timeout=60)
    one_line_failure(done, f"port {port} is in use by another process: choose another with --foxglove PORT", code=2)
    assert "virtual agent" not in done.stderr and time.monotonic() - began < 20
    assert not (tmp_path / "rec").exists()


def test_foxglove_without_a_port_takes_the_default() -> None:
    assert with_flag_value(["run", "--foxglove"]) == ["run", "--foxglove", "8765"]
    assert with_flag_value(["view", "--foxglove", "hub://1"]) == ["view", "--foxglove", "8765", "hub://1"]
    assert with_flag_value(["run", "--foxglove", "0", "sim://"]) == ["run", "--foxglove", "0", "sim://"]


def test_the_live_layout_is_current_and_shows_what_the_server_offers() -> None:
    from groundstation.view.foxglove.console import LOG_TOPIC
    from scripts.foxglove_layout import BOUNDS_SCRIPT, BOUNDS_TOPIC, LIVE_OUT, VOLTS_TOPIC, live_layout

    shipped = json.loads(LIVE_OUT.read_text())
    assert shipped == live_layout(), "docs/foxglove/live-layout.json is stale: run python scripts/foxglove_layout.py"
    panels = shipped["configById"]
    buttons = {config["serviceName"] for name, config in panels.items() if name.startswith("CallService!")}
    assert buttons == set(REQUESTS)  # a button for every control: hover, target, mark and dump too
    assert panels["RosOut!log"]["topicToRender"] == LOG_TOPIC  # the agent's log and the run's events
    assert panels["Plot!battery"]["paths"][0]["value"] == f"{VOLTS_TOPIC}.battery_v"  # volts, as dive says
    assert {config["imageMode"]["imageTopic"] for name, config in panels.items() if name.startswith("Image!")} == \
        {VALUE_TOPIC, POLICY_TOPIC}
    assert any(name.startswith("Parameters!") for name in panels)
    messages = {cls.DEFINITION.name: cls for cls in message_classes().values()}
    paths = [path["value"] for config in panels.values() for path in config.get("paths", [])]
    paths.append(panels["Indicator!mode"]["path"])
    # depth drawn downward, as the Rerun view draws it: Foxglove's Plot cannot flip an axis, so z up = -depth
    assert [p["value"] for p in panels["Plot!depth"]["paths"]][0] == "/agent/SAMPLE.depth_m.@negative"
    assert "z up = -depth" in panels["Plot!depth"]["title"] and "-start.target_depth_m" in BOUNDS_SCRIPT
    for path in paths:  # every field plotted is in the schema of the channel the server publishes
        topic, field = re.sub(r"\.@\w+$", "", path).rsplit(".", 1)  # a math modifier (.@negative) off
        if topic in (BOUNDS_TOPIC, VOLTS_TOPIC):
            continue  # the layout's own user scripts
        name = topic.removeprefix("/agent/")
        assert field in message_schema(messages[name])["properties"], path


def test_a_policy_redraws_its_episodes_values_with_the_untried_cells_grey() -> None:
    """The agent sends VALUES, then POLICY: the value image is drawn again once the policy says which cells were
    never left (in a real server, read by the protocol client)."""
    import foxglove

    from groundstation.session.dumps import Dump
    from groundstation.view.foxglove.images import DumpImages
    from protocol import DumpKind

    context = foxglove.Context()
    images = DumpImages(context)
    server = foxglove.start_server(port=0, context=context)
    try:
        with FoxgloveClient.connected(server.port) as fox:
            assert fox.pump(lambda: {VALUE_TOPIC, POLICY_TOPIC} <= set(fox.channels), 5)
            values, policy = fox.subscribe(VALUE_TOPIC), fox.subscribe(POLICY_TOPIC)
            time.sleep(0.2)  # the subscriptions reach the server
            states = 10 * 10 + 1  # the default grid and the terminal state
            images.publish(Dump(1, DumpKind.VALUES, 7, struct.pack(f"<{states}f", *range(states))), time.time_ns())
            images.publish(Dump(2, DumpKind.POLICY, 7, bytes([0, 1, 255] * 33 + [0, 0])), time.time_ns())
            assert fox.pump(lambda: len(fox.messages.get(values, [])) == 2 and len(fox.messages.get(policy, [])) == 1)
            assert fox.channels[VALUE_TOPIC]["schemaName"] == "foxglove.RawImage"
            assert len(fox.messages[values][1]) > 320 * 320 * 3  # rgb8, one 32-pixel block per cell of the 10 x 10
    finally:
        server.stop()


def test_publishing_that_fails_stops_publishing_not_the_run() -> None:
    """On a run's own session a listener that raises stops the run; Foxglove's publisher says so once instead."""
    import foxglove

    from groundstation.session.events import EventKind, LinkEvent
    from groundstation.view.foxglove.channels import FoxgloveChannels

    said: list[str] = []
    channels = FoxgloveChannels(foxglove.Context(), on_failure=said.append)

    def broken(*args: object) -> foxglove.Channel:
        raise RuntimeError("the SDK gave up")

    channels.channel = broken  # type: ignore[method-assign]
    for _ in range(3):
        channels.on_event(LinkEvent(EventKind.MARKER, time.time_ns(), "x", {"text": "x"}))  # raises nothing
    assert said == ["Foxglove stopped publishing: RuntimeError: the SDK gave up"]


def test_a_late_subscriber_gets_its_channels_history_alone_and_bounded() -> None:
    """The run's server as `dive run` has it (no agent needed: frames fed as its session would): a client that
    subscribes late is sent what it missed, in order and to it alone; the client subscribed before gets nothing
    twice. Larger than the SDK's default per-client queue (1024), which would drop the oldest."""
    from groundstation.session.dumps import Dump
    from groundstation.view.foxglove.live import FoxgloveLive
    from protocol import DumpKind
    from tests.groundstation.recording_fixtures import received, sample

    live = FoxgloveLive(0)
    try:
        with FoxgloveClient.connected(live.port) as early:
            live.channels.on_received(received(sample(0), 1))
            assert early.pump(lambda: "/agent/SAMPLE" in early.channels, 5)
            first = early.subscribe("/agent/SAMPLE")
            assert early.pump(lambda: len(early.messages.get(first, [])) == 1, 5)  # its own history: sample 0
            for i in range(1, 3000):
                live.channels.on_received(received(sample(i), i + 1))
            with FoxgloveClient.connected(live.port) as late:
                assert late.pump(lambda: "/agent/SAMPLE" in late.channels, 5)
                subscription = late.subscribe("/agent/SAMPLE")
                assert late.pump(lambda: len(late.messages.get(subscription, [])) >= 3000, 10)
                assert [json.loads(body)["sample"] for body in late.messages[subscription]] == list(range(3000))
            early.pump(lambda: False, 0.3)
            assert [json.loads(body)["sample"] for body in early.messages[first]] == list(range(3000))
        # the newest value and policy images, drawn before the client came
        live.channels.publish_dump(Dump(2, DumpKind.POLICY, 7, bytes([0, 1, 255] * 33 + [0, 0])), 123_456_789)
        with FoxgloveClient.connected(live.port) as viewer:
            assert viewer.pump(lambda: {POLICY_TOPIC, "/dump/POLICY"} <= set(viewer.channels), 5)
            images, dumps = viewer.subscribe(POLICY_TOPIC), viewer.subscribe("/dump/POLICY")
            assert viewer.pump(lambda: bool(viewer.messages.get(images)) and bool(viewer.messages.get(dumps)), 5)
            assert viewer.log_times[images] == viewer.log_times[dumps] == [123_456_789]
    finally:
        live.close()


def test_the_history_keeps_the_last_minutes_every_episode_and_the_newest_dump() -> None:
    from groundstation.view.foxglove.history import ChannelHistory, FoxgloveHistoryConfig

    history = ChannelHistory(FoxgloveHistoryConfig(window_s=60.0, max_per_topic=100, max_whole=1000))
    for second in range(200):  # one message a second of each
        for topic in ("/agent/SAMPLE", "/agent/EPISODE_END", "/dump/POLICY"):
            history.keep_bytes(topic, second * 1_000_000_000, b"%d" % second)
    assert [int(body) for _, body in history.replay("/agent/SAMPLE")] == list(range(139, 200))  # last minute
    assert len(history.replay("/agent/EPISODE_END")) == 200  # the learning curve whole
    assert history.replay("/dump/POLICY") == [(199_000_000_000, b"199")]
    for i in range(300):  # at --speed max a minute holds more than max_per_topic: the newest are kept
        history.keep_bytes("/agent/HEARTBEAT", 300_000_000_000 + i, b"x")
    assert len(history.replay("/agent/HEARTBEAT")) == 100 and history.replay("/nothing") == []
