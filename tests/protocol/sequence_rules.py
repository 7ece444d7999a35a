"""The rules SPEC.md 1.2 states that tests/vectors/sequences.jsonl shows (sessions, ACK memory, episode order), as
checks on a list of frames: the vectors themselves and any agent's answers to their ground frames are held to them."""

from __future__ import annotations

from typing import Any

from protocol import AckResult, EndReason, Mode

Frames = list[dict[str, Any]]


def shown(frames: Frames) -> Frames:
    """The frames of an example, without the `{"elided": N}` markers."""
    return [f for f in frames if "elided" not in f]


def check_session_start(frames: Frames) -> None:
    """SPEC s. 4: the agent's HELLO on the new link, the ground's flush and HELLO, the agent's answer."""
    frames = shown(frames)
    assert [(f["dir"], f["msg"]) for f in frames][:3] == [("a", "HELLO"), ("g", "HELLO"), ("a", "HELLO")]
    assert bytes.fromhex(frames[1]["wire_hex"])[0] == 0  # the ground flushes with 0x00 first


def check_reused_seq_is_executed(session: Frames, reconnect: Frames) -> None:
    """SPEC s. 5: a new session empties the ACK memory: a command reusing a (msg_id, seq) is executed; the missed
    SAMPLEs come back replayed and LOG_RANGE counts them."""
    session, reconnect = shown(session), shown(reconnect)
    again = [f for f in reconnect if f["dir"] == "g" and f["msg"] == "PARAM_GET"][0]
    first = [f for f in session if f["dir"] == "g" and f["msg"] == "PARAM_GET"][0]
    assert again["wire_hex"] == first["wire_hex"]  # the same (msg_id, seq)
    after = reconnect[reconnect.index(again) + 1:]
    assert after[0]["msg"] == "ACK" and after[0]["fields"]["result"] == AckResult.ACCEPTED
    assert after[1]["msg"] == "PARAM_VALUE"  # executed: the ACK memory was emptied by the session's start
    replayed = [f["fields"]["sample"] for f in after if f["msg"] == "SAMPLE"]
    log_range = [f for f in after if f["msg"] == "LOG_RANGE"][0]["fields"]
    assert replayed and log_range["replayed"] == len(replayed)


def check_episode_order(frames: Frames) -> None:
    """SPEC s. 6: an episode's first SAMPLE right after EPISODE_START; the ending step's SAMPLE (action 255) right
    before a natural EPISODE_END; CMD_STOP's ACK before the EPISODE_END aborted, then SURFACING."""
    frames = shown(frames)
    starts = [i for i, f in enumerate(frames) if f["msg"] == "EPISODE_START"]
    ends = [i for i, f in enumerate(frames) if f["msg"] == "EPISODE_END"]
    assert len(starts) == len(ends) == 2
    for i in starts:  # the first SAMPLE after EPISODE_START is the episode's first, with the index it announced
        first = next(f for f in frames[i + 1:] if f["msg"] == "SAMPLE")["fields"]
        assert first["sample"] == frames[i]["fields"]["sample"] and first["mode"] == Mode.LEARNING
        assert first["step"] == 0
    natural, aborted = frames[ends[0]], frames[ends[1]]
    last = frames[ends[0] - 1]["fields"]  # the ending step's SAMPLE comes right before its EPISODE_END
    assert natural["fields"]["reason"] != EndReason.ABORTED
    assert last["action"] == 255 and last["sample"] == natural["fields"]["sample"]
    assert aborted["fields"]["reason"] == EndReason.ABORTED
    before = frames[ends[1] - 1]
    assert before["msg"] == "ACK" and frames[ends[1] - 2]["msg"] == "CMD_STOP"  # the ACK first (SPEC 5 and 6)
    samples = [f["fields"]["sample"] for f in frames[: ends[1]] if f["msg"] == "SAMPLE"]
    assert aborted["fields"]["sample"] == samples[-1]
    assert aborted["fields"]["episode"] == natural["fields"]["episode"] + 1
    assert next(f for f in frames[ends[1]:] if f["msg"] == "SAMPLE")["fields"]["mode"] == Mode.SURFACING


def check_learner_restart(frames: Frames) -> None:
    """SPEC 1.3 s. 6: after an accepted CMD_RESET_MODEL every frame carries the next generation, the first
    HEARTBEAT says episode 0, and the new learner's first episode is episode 1, its START and END of that
    generation."""
    frames = shown(frames)
    reset = next(i for i, f in enumerate(frames) if f["dir"] == "g" and f["msg"] == "CMD_RESET_MODEL")
    ack = next(f for f in frames[reset:] if f["dir"] == "a" and f["msg"] == "ACK")
    assert ack["fields"]["result"] == AckResult.ACCEPTED
    after = [f for f in frames[reset:] if f["dir"] == "a" and "generation" in f["fields"]]
    generations = {f["fields"]["generation"] for f in after}
    assert len(generations) == 1 and generations.pop() >= 2, after
    beat = next(f for f in after if f["msg"] == "HEARTBEAT")
    assert beat["fields"]["episode"] == 0
    episodes = [(f["msg"], f["fields"]["episode"]) for f in after if f["msg"].startswith("EPISODE_")]
    assert episodes[:2] == [("EPISODE_START", 1), ("EPISODE_END", 1)]
