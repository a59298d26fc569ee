"""Codec: round trips, resynchronisation after noise, splitting, signing, datagrams."""

from __future__ import annotations

import hashlib
import random

import pytest
from hypothesis import given
from hypothesis import strategies as st
from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from gcs_ppf.mavlink.codec import Codec, MAVLinkMessage, signing_key_from_text, signing_timestamp

KEY = bytes(range(32))


def _heartbeat(custom_mode: int = 15) -> MAVLinkMessage:
    return mavlink2.MAVLink_heartbeat_message(1, 3, 129, custom_mode, 4, 3)


def _position(t_ms: int) -> MAVLinkMessage:
    return mavlink2.MAVLink_global_position_int_message(
        t_ms, 473977420, 85455940, 788500, 300000, 2500, -120, 30, 9000
    )


def _vehicle_frames(n: int) -> list[bytes]:
    vehicle = Codec(1, 1)
    return [vehicle.encode(_position(i) if i % 2 else _heartbeat(i)) for i in range(n)]


def test_round_trip_keeps_ids_seq_and_fields() -> None:
    vehicle = Codec(7, 1)
    vehicle.seq = 254
    frames = [vehicle.encode(_heartbeat()) for _ in range(3)]
    msgs = Codec().parse(b"".join(frames))
    assert [m.get_seq() for m in msgs] == [254, 255, 0]
    assert all((m.get_srcSystem(), m.get_srcComponent()) == (7, 1) for m in msgs)
    assert msgs[0].custom_mode == 15
    assert vehicle.seq == 1


def test_byte_by_byte_feeding_yields_every_message_once() -> None:
    frames = _vehicle_frames(6)
    gcs = Codec()
    got: list[MAVLinkMessage] = []
    for byte in b"".join(frames):
        got += gcs.parse(bytes([byte]))
    assert [m.get_msgbuf() for m in got] == frames
    assert gcs.stats.messages == 6
    assert gcs.stats.errors == 0
    assert gcs.pending_bytes == 0


def test_bad_crc_is_dropped_and_the_next_frames_survive() -> None:
    frames = _vehicle_frames(4)
    broken = bytearray(frames[1])
    broken[-1] ^= 0xFF
    gcs = Codec()
    msgs = gcs.parse(b"".join([frames[0], bytes(broken), frames[2], frames[3]]))
    assert [m.get_msgbuf() for m in msgs] == [frames[0], frames[2], frames[3]]
    assert gcs.stats.framing_errors >= 1


def test_false_start_marker_does_not_swallow_the_frames_inside_its_length() -> None:
    """0xFD 0xFF … claims a 255-byte payload: the real frames inside it must still come out."""
    frames = _vehicle_frames(8)
    noise = bytes([0xFD, 0xFF, 0x00, 0x00, 0x00, 0x01, 0x01, 0x21, 0x00, 0x00])
    stream = noise + b"".join(frames) + bytes(300)  # enough bytes to complete the false frame
    gcs = Codec()
    msgs = gcs.parse(stream)
    assert [m.get_msgbuf() for m in msgs] == frames
    assert gcs.stats.errors >= 1


def test_signed_frame_header_with_unknown_incompat_flag_is_noise() -> None:
    frame = bytearray(_vehicle_frames(1)[0])
    frame[2] = 0x80
    gcs = Codec()
    assert gcs.parse(bytes(frame)) == []
    assert gcs.stats.framing_errors == 1


def test_unknown_message_id_is_skipped() -> None:
    frame = bytearray(_vehicle_frames(1)[0])
    frame[7:10] = (0xF0, 0xFF, 0x7F)  # no such message id
    good = _vehicle_frames(2)
    gcs = Codec()
    msgs = gcs.parse(bytes(frame) + b"".join(good))
    assert [m.get_msgbuf() for m in msgs] == good
    assert gcs.stats.unknown_messages == 1


def test_random_noise_never_raises_and_frames_after_it_survive() -> None:
    rng = random.Random(42)
    gcs = Codec()
    noise = bytes(rng.randrange(256) for _ in range(20_000))
    gcs.parse(noise)
    gcs.reset()
    frames = _vehicle_frames(3)
    assert [m.get_msgbuf() for m in gcs.parse(b"".join(frames))] == frames
    assert gcs.stats.bytes_skipped > 0


@given(st.lists(st.binary(max_size=64), max_size=20))
def test_any_chunks_of_bytes_never_raise(chunks: list[bytes]) -> None:
    gcs = Codec()
    for chunk in chunks:
        for msg in gcs.parse(chunk):
            assert msg.get_type() != "BAD_DATA"
    assert gcs.pending_bytes <= 280


@given(st.binary(max_size=200).filter(lambda b: 0xFD not in b and 0xFE not in b))
def test_noise_without_start_markers_costs_no_frame(noise: bytes) -> None:
    frames = _vehicle_frames(3)
    gcs = Codec()
    msgs = gcs.parse(noise + frames[0] + noise + frames[1] + frames[2] + noise)
    assert [m.get_msgbuf() for m in msgs] == frames
    assert gcs.stats.bytes_skipped == 3 * len(noise)


def test_mavlink1_frames_are_accepted() -> None:
    mav = mavlink2.MAVLink(None, srcSystem=9, srcComponent=1)
    frame = _heartbeat().pack(mav, force_mavlink1=True)
    assert frame[0] == 0xFE
    msgs = Codec().parse(frame)
    assert len(msgs) == 1
    assert msgs[0].get_srcSystem() == 9


def test_datagram_with_a_partial_frame_drops_only_the_partial_frame() -> None:
    frames = _vehicle_frames(3)
    gcs = Codec()
    msgs = gcs.parse_datagram(frames[0] + frames[1][:5])
    assert [m.get_msgbuf() for m in msgs] == [frames[0]]
    assert gcs.stats.truncated == 1
    assert [m.get_msgbuf() for m in gcs.parse_datagram(frames[2])] == [frames[2]]


def test_encode_rejects_values_that_do_not_fit() -> None:
    msg = mavlink2.MAVLink_heartbeat_message(1, 3, 300, 0, 4, 3)  # base_mode is a uint8
    with pytest.raises(ValueError, match="HEARTBEAT"):
        Codec().encode(msg)


def test_bad_ids_and_keys_are_rejected() -> None:
    with pytest.raises(ValueError, match="source ids"):
        Codec(0, 190)
    with pytest.raises(ValueError, match="32 bytes"):
        Codec(signing_key=b"short")
    with pytest.raises(ValueError, match="seq"):
        Codec().seq = 256


# -- signing ------------------------------------------------------------------------------
def test_signed_frames_round_trip_between_codecs_sharing_a_key() -> None:
    t0 = signing_timestamp(1_700_000_000.0)
    vehicle = Codec(1, 1, signing_key=KEY, signing_link_id=3, signing_timestamp=t0)
    gcs = Codec(signing_key=KEY, signing_timestamp=t0)
    frame = vehicle.encode(_heartbeat())
    assert frame[2] & 0x01  # MAVLINK_IFLAG_SIGNED
    assert len(frame) == 10 + 9 + 2 + 13
    assert vehicle.signing_timestamp == t0 + 1
    msgs = gcs.parse(frame)
    assert len(msgs) == 1
    assert msgs[0].get_signed()
    assert msgs[0].get_link_id() == 3


def test_wrong_key_and_unsigned_frames_are_rejected_when_signing() -> None:
    t0 = signing_timestamp(1_700_000_000.0)
    intruder = Codec(1, 1, signing_key=bytes(32), signing_timestamp=t0)
    unsigned = Codec(1, 1)
    gcs = Codec(signing_key=KEY, signing_timestamp=t0)
    assert gcs.parse(intruder.encode(_heartbeat())) == []
    assert gcs.parse(unsigned.encode(_heartbeat())) == []
    assert gcs.stats.rejected == 2
    lenient = Codec(signing_key=KEY, signing_timestamp=t0, accept_unsigned=True)
    assert len(lenient.parse(unsigned.encode(_heartbeat()))) == 1


def test_replayed_signed_frame_is_rejected() -> None:
    t0 = signing_timestamp(1_700_000_000.0)
    vehicle = Codec(1, 1, signing_key=KEY, signing_timestamp=t0)
    gcs = Codec(signing_key=KEY, signing_timestamp=t0)
    frame = vehicle.encode(_heartbeat())
    assert len(gcs.parse(frame)) == 1
    assert gcs.parse(frame) == []
    assert gcs.stats.rejected == 1


def test_signing_timestamp_epoch() -> None:
    assert signing_timestamp(1_420_070_400.0) == 0
    assert signing_timestamp(1_420_070_401.0) == 100_000
    assert signing_timestamp(0.0) == 0


def test_refusals_are_counted_by_kind_and_name_the_sender() -> None:
    t0 = signing_timestamp(1_700_000_000.0)
    gcs = Codec(signing_key=KEY, signing_timestamp=t0)
    wrong_key = Codec(9, 1, signing_key=bytes(32), signing_timestamp=t0)
    unsigned = Codec(8, 1)
    assert gcs.parse(wrong_key.encode(_heartbeat()) + unsigned.encode(_heartbeat())) == []
    s = gcs.stats
    assert (s.refused_unsigned, s.refused_bad_signature, s.rejected) == (1, 1, 2)
    assert gcs.last_refused == (8, 1, 0)  # system 8, component 1, HEARTBEAT
    # Without a key nothing is refused for its signature, signed or not.
    plain = Codec()
    assert len(plain.parse(wrong_key.encode(_heartbeat()) + unsigned.encode(_heartbeat()))) == 2
    assert plain.stats.refused_unsigned == plain.stats.refused_bad_signature == 0


def test_a_link_that_accepts_unsigned_frames_still_refuses_wrongly_signed_ones() -> None:
    t0 = signing_timestamp(1_700_000_000.0)
    lenient = Codec(signing_key=KEY, signing_timestamp=t0, accept_unsigned=True)
    assert lenient.accept_unsigned
    assert len(lenient.parse(Codec(8, 1).encode(_heartbeat()))) == 1
    forged = Codec(9, 1, signing_key=bytes(32), signing_timestamp=t0).encode(_heartbeat())
    assert lenient.parse(forged) == []
    assert lenient.stats.refused_bad_signature == 1
    assert not Codec(accept_unsigned=True).accept_unsigned  # no key: nothing to accept


def test_a_forged_frame_from_the_future_does_not_lock_out_the_genuine_stream() -> None:
    """pymavlink alone records the forger's timestamp for the stream before checking the
    signature; the vehicle's next genuine frames would then be refused as replays."""
    t0 = signing_timestamp(1_700_000_000.0)
    vehicle = Codec(1, 1, signing_key=KEY, signing_timestamp=t0)
    forger = Codec(1, 1, signing_key=bytes(32), signing_timestamp=t0 + 10**9)
    gcs = Codec(signing_key=KEY, signing_timestamp=t0)
    assert len(gcs.parse(vehicle.encode(_heartbeat()))) == 1
    assert gcs.parse(forger.encode(_heartbeat())) == []
    assert len(gcs.parse(vehicle.encode(_heartbeat()))) == 1
    # And a forger first on a stream leaves no trace of it either.
    fresh = Codec(signing_key=KEY, signing_timestamp=t0)
    assert fresh.parse(forger.encode(_heartbeat())) == []
    assert len(fresh.parse(vehicle.encode(_heartbeat()))) == 1


def test_the_signing_clock_follows_the_wall_clock_and_never_goes_back() -> None:
    t0 = signing_timestamp(1_700_000_000.0)
    codec = Codec(signing_key=KEY, signing_timestamp=t0)
    codec.advance_signing_clock(t0 + 500_000)  # 5 s later
    frame = codec.encode(_heartbeat())
    stamp = int.from_bytes(frame[-12:-6], "little")
    assert stamp == t0 + 500_000
    codec.advance_signing_clock(t0)  # the wall clock stepped back
    again = int.from_bytes(codec.encode(_heartbeat())[-12:-6], "little")
    assert again == stamp + 1


@pytest.mark.parametrize(
    ("text", "key"),
    [
        ("00" * 31 + "ff", bytes(31) + b"\xff"),
        ("  " + "ab" * 32 + "\n", bytes([0xAB]) * 32),
        ("my secret passphrase", hashlib.sha256(b"my secret passphrase").digest()),
        ("zz" * 32, hashlib.sha256(b"zz" * 32).digest()),  # not hex: a passphrase
    ],
)
def test_signing_key_from_text(text: str, key: bytes) -> None:
    assert signing_key_from_text(text) == key


def test_an_empty_signing_key_is_an_error() -> None:
    with pytest.raises(ValueError, match="empty"):
        signing_key_from_text(" \n")
