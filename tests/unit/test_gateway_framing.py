"""The legacy wire format: convention detection, framing both ways, bad input."""

from __future__ import annotations

import json
import struct

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from gateway import framing
from gateway.framing import (
    BodyLimits,
    ByteOrder,
    Convention,
    FrameDecoder,
    FramingError,
    encode_frame,
    parse_frame,
)
from gateway.messages import MessageError, Monitor
from schemas.errors import ErrorCode
from tests.legacy_client import APPENDIX_A_CLIENT_EXAMPLES, CONVENTIONS, frame, header

ORDER = {"big": ByteOrder.BIG, "little": ByteOrder.LITTLE, "ascii": ByteOrder.ASCII}


@pytest.mark.parametrize(("order", "counted"), CONVENTIONS)
@pytest.mark.parametrize("example", APPENDIX_A_CLIENT_EXAMPLES)
def test_every_appendix_example_is_detected_in_every_convention(
    example: str, order: str, counted: bool
) -> None:
    decoder = FrameDecoder()
    frames = decoder.feed(frame(example.encode(), order, counted))
    assert [f.value for f in frames] == [json.loads(example)]
    assert decoder.convention == Convention(ORDER[order], counted)


@pytest.mark.parametrize(("order", "counted"), CONVENTIONS)
def test_byte_by_byte_and_several_frames_in_one_read(order: str, counted: bool) -> None:
    bodies = [b'{"monitor":{"motors":1}}', b'{"walk":{"a":0,"stop":1,"x":0,"y":0}}'] * 3
    stream = b"".join(frame(b, order, counted) for b in bodies)
    one = FrameDecoder()
    got = []
    for i in range(len(stream)):
        got += one.feed(stream[i : i + 1])
    assert [f.body for f in got] == bodies
    many = FrameDecoder()
    assert [f.body for f in many.feed(stream)] == bodies


def test_a_size_both_byte_orders_could_mean_is_settled_by_the_json() -> None:
    # 512 bytes big-endian is 00 00 02 00; read little-endian that is 131072, also under the
    # maximum: only the big-endian reading gives a complete JSON value.
    body = json.dumps({"monitor": {"motors": 1, "pad": "x" * 470}}).encode()
    body = body + b" " * (512 - len(body))
    assert len(body) == 512
    decoder = FrameDecoder()
    assert decoder.feed(frame(body, "big", False))[0].value["monitor"]["motors"] == 1
    assert decoder.convention == Convention(ByteOrder.BIG, False)
    little = FrameDecoder()
    assert little.feed(frame(body, "little", False))[0].value["monitor"]["motors"] == 1
    assert little.convention == Convention(ByteOrder.LITTLE, False)


@pytest.mark.parametrize(("order", "counted"), CONVENTIONS)
def test_replies_use_the_senders_convention(order: str, counted: bool) -> None:
    conv = Convention(ORDER[order], counted)
    data = encode_frame({"orchestrate": {"status": 1}}, conv)
    body = b'{"orchestrate":{"status":1}}'
    assert data == frame(body, order, counted)


def test_a_header_in_no_convention_is_an_error() -> None:
    with pytest.raises(FramingError, match="not a message size in any supported convention") as e:
        FrameDecoder().feed(b"\x7f\x7f\x7f\x7f{}")
    assert e.value.code == ErrorCode.INVALID


def test_size_above_the_maximum_is_refused_before_reading_it() -> None:
    decoder = FrameDecoder(max_message=1000)
    with pytest.raises(FramingError, match="not a message size"):
        decoder.feed(struct.pack(">I", 5000))
    # Once the convention is known, a too-large header is named as such.
    decoder = FrameDecoder(max_message=1000)
    decoder.feed(frame(b"{}", "big", False))
    with pytest.raises(FramingError, match="above the maximum message size of 1000") as e:
        decoder.feed(struct.pack(">I", 5000))
    assert e.value.code == ErrorCode.OUT_OF_RANGE


@pytest.mark.parametrize(
    ("body", "needle"),
    [(b"\xff\xfe{}", "not valid UTF-8"), (b"{not json}", "not valid JSON"), (b"{}{}", "JSON")],
)
def test_bad_bodies_are_named(body: bytes, needle: str) -> None:
    with pytest.raises(FramingError, match=needle):
        FrameDecoder().feed(frame(body, "big", False))


def test_bad_body_after_detection() -> None:
    decoder = FrameDecoder()
    decoder.feed(frame(b"{}", "little", True))
    with pytest.raises(FramingError, match="not valid JSON"):
        decoder.feed(frame(b"{oops", "little", True))


def test_ascii_header_cannot_say_more_than_9999() -> None:
    conv = Convention(ByteOrder.ASCII, False)
    with pytest.raises(FramingError, match="4-digit ASCII header"):
        encode_frame({"camera": "x" * 10_000}, conv)


def test_outgoing_message_above_maximum_is_refused() -> None:
    with pytest.raises(FramingError, match="above the maximum"):
        encode_frame({"x": "y" * 100}, Convention(), max_message=50)


json_values = st.recursive(
    st.none() | st.booleans() | st.integers(-(10**6), 10**6) | st.text(max_size=20),
    lambda inner: (
        st.lists(inner, max_size=4) | st.dictionaries(st.text(max_size=8), inner, max_size=4)
    ),
    max_leaves=12,
)


@settings(max_examples=60, deadline=None)
@given(
    values=st.lists(
        st.dictionaries(st.text(max_size=8), json_values, max_size=4), min_size=1, max_size=4
    ),
    convention=st.sampled_from(CONVENTIONS),
    cut=st.integers(1, 64),
)
def test_round_trip_any_objects_any_chunking(
    values: list[dict], convention: tuple[str, bool], cut: int
) -> None:
    order, counted = convention
    stream = b"".join(frame(json.dumps(v).encode(), order, counted) for v in values)
    decoder = FrameDecoder()
    got = []
    for i in range(0, len(stream), cut):
        got += decoder.feed(stream[i : i + cut])
    assert [f.value for f in got] == values


@settings(max_examples=200, deadline=None)
@given(data=st.binary(max_size=200))
def test_random_bytes_give_frames_or_a_framing_error_never_anything_else(data: bytes) -> None:
    decoder = FrameDecoder(max_message=4096)
    try:
        decoder.feed(data)
    except FramingError as exc:
        assert exc.message
    assert decoder.buffered <= len(data)


def test_good_frames_before_a_break_are_kept_and_the_break_reported_next() -> None:
    decoder = FrameDecoder()
    data = frame(b'{"monitor":{"motors":1}}', "big", False) + b"\x7f\x7f\x7f\x7f"
    assert [f.value for f in decoder.feed(data)] == [{"monitor": {"motors": 1}}]
    assert decoder.error is not None and "above the maximum" in decoder.error.message
    with pytest.raises(FramingError):
        decoder.feed(b"")


MONITOR = b'{"monitor":{"motors":1}}'


def nested(depth: int) -> bytes:
    """A walk message whose value nests lists ``depth`` levels deep (the message adds one)."""
    return b'{"walk":' + b"[" * (depth - 1) + b"]" * (depth - 1) + b"}"


@pytest.mark.parametrize(
    "body",
    [
        b"[" * 5000 + b"]" * 5000,  # json would recurse until Python stops it
        b'{"x":' + b'{"y":' * 40 + b"1" + b"}" * 41,
        b"[" * 2000 + b'"]]}\\"["' + b"]" * 2000,  # brackets in a string are no nesting
        b'{"operate":{"all":0,"id":3,"position":' + b"1" * 5000 + b"}}",  # int() refuses
        b'{"walk":{"a":0,"stop":0,"x":1.' + b"5" * 5000 + b',"y":0}}',
    ],
    ids=["5000-levels", "42-levels", "string-brackets", "5000-digit-int", "5000-digit-float"],
)
@pytest.mark.parametrize("first", [True, False], ids=["first-message", "later-message"])
def test_a_body_beyond_the_limits_is_a_refused_frame_and_the_stream_goes_on(
    body: bytes, first: bool
) -> None:
    decoder = FrameDecoder()
    if not first:
        decoder.feed(frame(MONITOR, "little", True))
    frames = decoder.feed(frame(body, "little", True) + frame(MONITOR, "little", True))
    assert len(frames) == 2
    with pytest.raises(MessageError, match=r"deeper than 32|number of 50\d\d characters") as e:
        parse_frame(frames[0])
    assert e.value.code == ErrorCode.OUT_OF_RANGE
    assert parse_frame(frames[1]) == Monitor({"motors": True})
    assert decoder.convention == Convention(ByteOrder.LITTLE, True)


def test_the_limits_are_exact() -> None:
    decoder = FrameDecoder(limits=BodyLimits(max_depth=6, max_number_length=5))
    accepted = [nested(6), b'{"x":12345}', b'{"x":-1234}', b'{"x":1e-10}']
    refused = [nested(7), b'{"x":123456}', b'{"x":-12345}', b'{"x":1.5e-10}']
    frames = decoder.feed(b"".join(frame(b) for b in accepted + refused))
    assert [f.error is None for f in frames] == [True] * 4 + [False] * 4
    # Brackets inside strings are text, not nesting.
    assert decoder.feed(frame(b'{"x":"' + b"[" * 100 + b'"}'))[0].error is None


@pytest.mark.parametrize(
    "body",
    [
        b'{"x":' + b"1" * 100 + b",}",
        b"[" * 5000,
        b"[" * 5000 + b"]" * 4999 + b"}",
        b"[" * 2000 + b'"' + b'\\"' * 20000,  # one string that never ends
    ],
    ids=["long-number", "5000-open", "5000-mismatched", "escaped-quotes"],
)
@pytest.mark.parametrize("first", [True, False], ids=["first-message", "later-message"])
def test_an_invalid_body_is_still_a_framing_error_however_deep_or_long(
    body: bytes, first: bool
) -> None:
    # Limits do not hide that the body is no JSON: the connection is closed.
    decoder = FrameDecoder()
    if not first:
        decoder.feed(frame(MONITOR))
    with pytest.raises(FramingError, match="not valid JSON"):
        decoder.feed(frame(body))


def test_a_header_above_the_incoming_maximum_is_refused_before_its_body_arrives() -> None:
    decoder = FrameDecoder(max_message=1024)
    decoder.feed(frame(MONITOR))
    with pytest.raises(FramingError, match="2000 bytes, above the maximum message size of 1024"):
        decoder.feed(header(2000))  # nothing of the body parked
    assert decoder.buffered == 4


def test_a_first_message_dribbled_in_is_parsed_once_per_reading(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    # 00 00 01 00 is 256 bytes big-endian and 65536 little-endian: while the longer reading
    # waits for its bytes, the shorter (complete, not JSON) is not parsed again on every read.
    body = json.dumps({"monitor": {"motors": 1, "pad": ""}}).encode()
    body = body.replace(b'""', b'"' + b"x" * (65536 - len(body)) + b'"')
    assert len(body) == 65536
    data = frame(body, "little", False)
    parsed: list[int] = []
    real = framing.parse_body

    def counted(body: bytes, limits: BodyLimits) -> object:
        parsed.append(len(body))
        return real(body, limits)

    monkeypatch.setattr(framing, "parse_body", counted)
    decoder = FrameDecoder(max_message=65536)
    reads = range(0, len(data) - 1, 997)
    for i in reads:
        assert decoder.feed(data[i : min(i + 997, len(data) - 1)]) == []
    assert decoder.feed(data[-1:])[0].value["monitor"]["motors"] == 1
    # Four readings (big/little, header counted or not), each parsed once, and the frame itself.
    assert len(parsed) <= 5 < len(reads)
