"""Message.pack_values, the senders' fast path: the same payload bytes as building the message and packing it."""

from __future__ import annotations

import pytest
from hypothesis import HealthCheck, given, settings

from protocol import FrameEncoder, StreamDecoder, definitions, message_class
from protocol.errors import PayloadError
from protocol.messages import Sample
from protocol.registry import Message
from tests.protocol.strategies import messages_of

FAST = settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])


@pytest.mark.parametrize("definition", definitions(), ids=lambda d: d.name)
def test_pack_values_gives_the_bytes_of_the_built_message(definition) -> None:  # type: ignore[no-untyped-def]
    cls = message_class(definition.msg_id)

    @FAST
    @given(message=messages_of(definition))
    def check(message: Message) -> None:
        values = [getattr(message, f.name) for f in definition.fields]
        assert cls.pack_values(*values) == message.pack()

    check()


def test_a_sample_packed_from_values_decodes_to_those_values() -> None:
    values = (1_234_567, 42, 3, 17, 104250.0, 0.25, -0.5, 65.0, 67.5, -10.0, 5, 255, 2)  # float32-exact
    payload = Sample.pack_values(*values)
    frames = StreamDecoder().feed(FrameEncoder().encode_payload(Sample.MSG_ID, payload).wire)
    assert frames[0].message == Sample(*values)
    assert FrameEncoder().encode_payload(Sample.MSG_ID, payload).wire == FrameEncoder().encode(Sample(*values)).wire


def test_pack_values_rejects_out_of_range_values_like_pack() -> None:
    values = (0, 0, 0, 0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 70_000, 0, 0)  # state is a u16
    with pytest.raises(PayloadError):
        Sample.pack_values(*values)
    with pytest.raises(PayloadError):
        Sample(*values).pack()


@pytest.mark.parametrize("definition", definitions(), ids=lambda d: d.name)
def test_unpack_from_a_frame_equals_unpack_of_the_slice(definition) -> None:  # type: ignore[no-untyped-def]
    cls = message_class(definition.msg_id)

    @FAST
    @given(message=messages_of(definition))
    def check(message: Message) -> None:
        payload = message.pack()
        frame = b"\x01\x02\x03" + payload + b"\xaa\xbb"
        for cut in (0, 1, len(payload) // 2):  # short payloads are zero-extended either way
            end = 3 + len(payload) - cut
            assert cls.unpack_from(frame, 3, end) == cls.unpack(frame[3:end])
        assert cls.unpack_from(frame, 3, len(frame)) == cls.unpack(frame[3:])  # extra bytes ignored

    check()
