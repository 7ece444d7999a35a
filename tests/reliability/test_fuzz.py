"""Fuzzing with hypothesis: the decoder, the agent's command handler (signing on) and the ground station's session
handler take random and mutated frames without an exception escaping or a state going wrong.
(Longer runs: fuzz/README.md, atheris.)"""

from __future__ import annotations

from collections import Counter

from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from groundstation.links.memory import MemoryLink
from groundstation.session.agent_session import Session
from protocol import AckResult, FrameEncoder, Mode, Signer, StreamDecoder, definitions, messages
from protocol.frame import MAX_CHUNK
from protocol.registry import Direction, Message
from tests.protocol.strategies import any_message, messages_of
from tests.simulator.agent_trace import in_process_agent

KEY = bytes(range(32))
COMMANDS = st.one_of([messages_of(d) for d in definitions() if d.direction == Direction.GROUND_TO_AGENT])
TELEMETRY = st.one_of([messages_of(d) for d in definitions() if d.direction != Direction.GROUND_TO_AGENT])
# a frame, then how to damage it: (position, new byte) pairs and an optional cut
MUTATIONS = st.lists(st.tuples(st.integers(0, 300), st.integers(0, 255)), max_size=3)


def _mutate(wire: bytes, changes: list[tuple[int, int]], cut: int | None) -> bytes:
    data = bytearray(wire)
    for position, value in changes:
        data[position % len(data)] = value
    return bytes(data[:cut] if cut is not None else data)


@settings(max_examples=300, deadline=None)
@given(items=st.lists(st.one_of(st.binary(max_size=400), st.tuples(any_message, st.booleans(), MUTATIONS,
                                                                    st.none() | st.integers(0, 300))), max_size=20))
def test_the_decoder_never_raises_and_its_memory_and_counts_stay_sane(items: list[object]) -> None:
    decoder = StreamDecoder()
    plain, signed = FrameEncoder(), FrameEncoder(signer=Signer(KEY, 1))
    frames = 0
    for item in items:
        if isinstance(item, bytes):
            data = item
        else:
            message, sign, changes, cut = item  # type: ignore[misc]
            data = _mutate((signed if sign else plain).encode(message).wire, changes, cut)
        frames += len(decoder.feed(data))
        assert decoder.buffered_bytes <= MAX_CHUNK
    assert decoder.stats.frames == frames
    # still in step: a clean frame after the garbage decodes (after one delimiter to close any open chunk)
    assert [f.message for f in decoder.feed(b"\x00" + plain.encode(messages.Stop()).wire)][-1:] == [messages.Stop()]


@settings(max_examples=120, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(items=st.lists(st.tuples(COMMANDS, st.sampled_from(["signed", "unsigned", "wrong key"]), MUTATIONS,
                                st.booleans()), min_size=1, max_size=10))
def test_the_signing_agent_answers_every_command_once_and_runs_only_signed_ones_or_a_surface(
        items: list[object]) -> None:
    link, program, out = in_process_agent(KEY)
    encoders = {"signed": FrameEncoder(signer=Signer(KEY, 2)), "unsigned": FrameEncoder(100),
                "wrong key": FrameEncoder(200, signer=Signer(bytes(32), 2))}
    reader = StreamDecoder()
    answered: Counter[int] = Counter()
    for message, how, changes, damage in items:  # type: ignore[misc]
        encoded = encoders[how].encode(message)
        mode_before, rejects_before = program.mode, link.signing_rejects
        # a leading 0x00 closes whatever a damaged frame before left open (SPEC s. 1: senders may flush so), so a
        # damaged frame may be answered late, together with this one
        link.receive(_mutate(encoded.wire, changes, None) if damage else b"\x00" + encoded.wire)
        acks = [f.message for f in reader.feed(bytes(out)) if isinstance(f.message, messages.Ack)]
        out.clear()
        answered.update(a.cmd_seq for a in acks)
        assert all(count == 1 for count in answered.values())  # a command is never answered twice
        mine = [a for a in acks if a.cmd_seq == encoded.seq]
        if len(acks) == 1 and acks[0].result == AckResult.UNAUTHORIZED:
            assert link.signing_rejects == rejects_before + 1 and program.mode == mode_before
        if not damage:
            assert len(mine) == 1
            # SPEC 1.2 s. 12: anyone may make it surface (the fail-safe), nobody else may make it do anything
            refused = how != "signed" and not isinstance(message, messages.Surface)
            assert (mine[0].result == AckResult.UNAUTHORIZED) == refused
        for _ in range(2):
            program.step()
            link.tick()
        assert program.mode in set(Mode)


def _session() -> Session:
    ground, agent_side = MemoryLink.pair()
    agent_side.open()
    ground.open()
    session = Session(ground)
    session.agent_hello = messages.Hello(protocol_version=1, node_kind=1)  # as after connect(): frames are delivered
    return session


@settings(max_examples=200, deadline=None)
@given(items=st.lists(st.one_of(st.binary(max_size=300), st.tuples(TELEMETRY, st.booleans(), MUTATIONS)),
                      max_size=25))
def test_the_session_handler_survives_any_agent_traffic(items: list[object]) -> None:
    session = _session()
    encoder = FrameEncoder()
    seen: list[Message] = []
    session.add_listener(session.rx_listener(lambda r: seen.append(r.message)))
    for item in items:
        if isinstance(item, bytes):
            data = item
        else:
            message, replayed, changes = item  # type: ignore[misc]
            data = _mutate(encoder.encode(message, 2 if replayed else 0).wire, changes, None)
        for frame in session.decoder.feed(data):
            session._handle(frame, 0)  # what the reader thread does with each frame
    backfilled = [m.sample for m in seen if isinstance(m, messages.Sample)]
    held = session.backfill.held
    assert all(index in held for index in backfilled)  # every delivered sample is accounted for in the gap tracker
    assert len(held) == len(set(backfilled))  # and nothing else is
    assert session.backfill.missing() == held.missing(end=max(session.backfill.known_end, held.end or 0))
