"""MAVLink 2 framing and (optional) signing for one peer, with no I/O and no clock.

The only module that touches pymavlink's codec.  Each peer gets its own ``Codec``: a
``pymavlink.dialects.v20.ardupilotmega.MAVLink(None, srcSystem, srcComponent)`` (the dialect
module is imported directly, so nothing depends on the ``MAVLINK20`` environment variable).

Framing is done here rather than by pymavlink's ``parse_buffer``: after a frame whose header or
CRC is wrong (or whose message id it does not know, which is what noise after a 0xFD mostly
looks like), pymavlink drops the whole claimed length and every real frame hidden in it; this
parser drops only the start byte and searches again, so noise costs no good frame.
pymavlink's ``decode`` still unpacks the payload and checks signatures.
"""

from __future__ import annotations

import hashlib
import struct
from dataclasses import dataclass
from typing import Any

from pymavlink.dialects.v20 import ardupilotmega as mavlink2

MAVLinkMessage = Any
"""A pymavlink message object (pymavlink ships no type information)."""

STX_V1 = 0xFE
STX_V2 = 0xFD
_HEADER_LEN_V1 = 6
_HEADER_LEN_V2 = 10
_CRC_LEN = 2
_SIGNATURE_LEN = 13
_IFLAG_SIGNED = 0x01
SIGNING_KEY_LEN = 32
"""MAVLink 2 signing keys are 32 bytes (a SHA-256 of the passphrase, by convention)."""

SIGNING_EPOCH_UNIX_S = 1_420_070_400.0
"""2015-01-01T00:00:00Z: the origin of MAVLink 2 signing timestamps."""


def signing_timestamp(unix_s: float) -> int:
    """MAVLink 2 signing timestamp (10 µs units since 2015-01-01 UTC) of UNIX time ``unix_s``."""
    return max(0, int((unix_s - SIGNING_EPOCH_UNIX_S) * 100_000))


def signing_key_from_text(text: str) -> bytes:
    """The 32-byte signing key that ``text`` names: 64 hex digits as they are, anything else
    (a passphrase) hashed with SHA-256, as MAVProxy's ``signing setup PASSPHRASE`` does.

    Raises ValueError for an empty text (surrounding whitespace is ignored)."""
    text = text.strip()
    if not text:
        raise ValueError("signing key is empty")
    if len(text) == 2 * SIGNING_KEY_LEN:
        try:
            return bytes.fromhex(text)
        except ValueError:
            pass
    return hashlib.sha256(text.encode("utf-8")).digest()


def guard_stream_timestamps(mav: Any) -> None:
    """Make ``mav`` (a pymavlink ``MAVLink``) forget the timestamp of a frame whose signature
    is wrong.  pymavlink records a stream's timestamp before it checks the signature
    (``MAVLink.check_signature``), so one forged frame with a far-future timestamp would
    make every genuine frame of that stream (link id, system, component) look like a replay,
    and be refused, until the forger's timestamp is reached (the C library records it only
    after the check)."""
    check = mav.check_signature

    def checked(msgbuf: bytearray, src_system: int, src_component: int) -> bool:
        streams = mav.signing.stream_timestamps
        stream = (msgbuf[-13], src_system, src_component)
        before = streams.get(stream)
        ok = bool(check(msgbuf, src_system, src_component))
        if not ok:
            if before is None:
                streams.pop(stream, None)
            else:
                streams[stream] = before
        return ok

    mav.check_signature = checked


@dataclass(frozen=True, slots=True)
class CodecStats:
    """What ``Codec.parse`` has seen so far."""

    messages: int = 0
    """Frames decoded into messages."""
    bytes_skipped: int = 0
    """Bytes outside any frame (noise before a start marker)."""
    framing_errors: int = 0
    """Frames with a bad CRC or header; parsing resumed one byte after their start marker."""
    unknown_messages: int = 0
    """Frames of a message id this dialect lacks (their CRC cannot be checked, so they are
    treated as noise: parsing resumed one byte after their start marker)."""
    rejected: int = 0
    """Frames with a good CRC that did not decode: bad or missing signature, bad payload."""
    refused_unsigned: int = 0
    """Of ``rejected``: unsigned frames refused because signing is on (and unsigned frames
    are not accepted)."""
    refused_bad_signature: int = 0
    """Of ``rejected``: signed frames whose signature is wrong (another key) or whose
    timestamp is not newer than the last of their stream (a replay)."""
    truncated: int = 0
    """Partial frames dropped at the end of a datagram."""

    @property
    def errors(self) -> int:
        """Every frame, or noise that looked like one, that was dropped."""
        return self.framing_errors + self.unknown_messages + self.rejected + self.truncated


class Codec:
    """MAVLink 2 (ardupilotmega dialect) codec for one peer: bytes in → messages, message → bytes.

    ``signing_key`` (32 bytes) turns on MAVLink 2 signing: every encoded frame is signed with
    ``signing_link_id`` and a timestamp that starts at ``signing_timestamp`` (10 µs units since
    2015, see ``signing_timestamp()``) and grows by one per frame and with signed frames received;
    incoming frames must then carry a valid signature unless ``accept_unsigned``.  The shell
    keeps the timestamp near the wall clock with ``advance_signing_clock`` (the MAVLink
    signing spec: monotonic, and a receiver refuses a new stream more than a minute behind).
    """

    def __init__(
        self,
        source_system: int = 255,
        source_component: int = 190,
        *,
        signing_key: bytes | None = None,
        signing_link_id: int = 0,
        signing_timestamp: int = 0,
        accept_unsigned: bool = False,
    ) -> None:
        if not (1 <= source_system <= 255 and 0 <= source_component <= 255):
            raise ValueError(
                f"source ids must be system 1..255 and component 0..255, "
                f"got {source_system}/{source_component}"
            )
        self._mav: Any = mavlink2.MAVLink(
            None, srcSystem=source_system, srcComponent=source_component
        )
        self._buf = bytearray()
        self._stats = CodecStats()
        self._frame_signed = False  # of the frame being decoded (see the callback below)
        self._accept_unsigned = accept_unsigned and signing_key is not None
        self.last_refused: tuple[int, int, int] | None = None
        """(system id, component id, message id) of the last frame refused for its
        signature (or for having none)."""
        if signing_key is not None:
            if len(signing_key) != SIGNING_KEY_LEN:
                raise ValueError(
                    f"signing_key must be {SIGNING_KEY_LEN} bytes, got {len(signing_key)}"
                )
            if not 0 <= signing_link_id <= 255:
                raise ValueError(f"signing_link_id must be 0..255, got {signing_link_id}")
            if signing_timestamp < 0:
                raise ValueError(f"signing_timestamp must be >= 0, got {signing_timestamp}")
            signing = self._mav.signing
            signing.secret_key = bytes(signing_key)
            signing.link_id = signing_link_id
            signing.timestamp = signing_timestamp
            signing.sign_outgoing = True
            guard_stream_timestamps(self._mav)
            # pymavlink asks this callback of wrongly signed frames too: only frames that
            # carry no signature at all are let through, and only with ``accept_unsigned``.
            signing.allow_unsigned_callback = lambda _mav, _msg_id: (
                accept_unsigned and not self._frame_signed
            )

    # -- properties ------------------------------------------------------------------------
    @property
    def source_system(self) -> int:
        return int(self._mav.srcSystem)

    @property
    def source_component(self) -> int:
        return int(self._mav.srcComponent)

    @property
    def seq(self) -> int:
        """Sequence number of the next encoded frame (0..255, wraps)."""
        return int(self._mav.seq)

    @seq.setter
    def seq(self, value: int) -> None:
        if not 0 <= value <= 255:
            raise ValueError(f"seq must be 0..255, got {value}")
        self._mav.seq = value

    @property
    def signing(self) -> bool:
        return self._mav.signing.secret_key is not None

    @property
    def accept_unsigned(self) -> bool:
        """Signing is on and unsigned frames are accepted all the same."""
        return self._accept_unsigned

    @property
    def signing_timestamp(self) -> int:
        """The timestamp the next signed frame carries (10 µs units since 2015)."""
        return int(self._mav.signing.timestamp)

    def advance_signing_clock(self, timestamp: int) -> None:
        """Let the next signed frame carry at least ``timestamp`` (10 µs units since 2015, from
        the wall clock: ``signing_timestamp(time.time())``); never moves it backwards, so
        the frames' timestamps stay strictly increasing whatever the wall clock does."""
        signing = self._mav.signing
        if timestamp > signing.timestamp:
            signing.timestamp = timestamp

    @property
    def stats(self) -> CodecStats:
        return self._stats

    @property
    def pending_bytes(self) -> int:
        """Bytes held back as the start of a frame not yet complete."""
        return len(self._buf)

    # -- encoding --------------------------------------------------------------------------
    def encode(self, msg: MAVLinkMessage) -> bytes:
        """One MAVLink 2 frame for ``msg`` from this codec's ids, with the next sequence number.

        Raises ValueError if a field does not fit its wire type.
        """
        try:
            frame = bytes(msg.pack(self._mav))
        except (struct.error, TypeError, OverflowError) as exc:
            raise ValueError(f"cannot encode {msg.get_type()}: {exc}") from exc
        self._mav.seq = (self._mav.seq + 1) % 256
        return frame

    # -- decoding --------------------------------------------------------------------------
    def parse(self, data: bytes) -> list[MAVLinkMessage]:
        """Messages completed by ``data`` (a chunk of a byte stream); never raises on bad input.

        A frame split across calls is completed by the next call.  Noise, frames with a bad
        CRC, unknown message ids and badly signed frames are dropped and counted in ``stats``.
        """
        buf = self._buf
        buf += data
        out: list[MAVLinkMessage] = []
        skipped = framing = unknown = rejected = unsigned = bad_sig = 0
        signing = self._mav.signing.secret_key is not None
        i = 0
        n = len(buf)
        while i < n:
            start = _next_stx(buf, i)
            if start < 0:
                skipped += n - i
                i = n
                break
            skipped += start - i
            i = start
            length = _frame_length(buf, i)
            if length is None:
                break  # header incomplete
            if length < 0:
                framing += 1  # impossible header: resynchronise after this marker
                i += 1
                continue
            if n - i < length:
                break  # frame incomplete
            frame = bytearray(buf[i : i + length])
            signed = frame[0] == STX_V2 and bool(frame[2] & _IFLAG_SIGNED)
            self._frame_signed = signed
            try:
                # pymavlink checks the CRC before anything else (the signature's counters
                # and timestamps included): a frame it decodes is whole, and only a frame
                # it refuses needs telling apart from noise (``_check_frame``).
                out.append(_decode(self._mav, frame))
            except Exception as exc:  # MAVError, struct.error, ...: all mean "drop it"
                status = _check_frame(frame)
                if status != _OK:
                    # Noise that looks like a start marker, or a frame we cannot verify:
                    # resume one byte on, so that no good frame hidden inside its claimed
                    # length is lost.
                    if status == _BAD:
                        framing += 1
                    else:
                        unknown += 1
                    i += 1
                    continue
                rejected += 1
                if signing and str(exc) == "Invalid signature":
                    if signed:
                        bad_sig += 1
                    else:
                        unsigned += 1
                    self.last_refused = _frame_ids(frame)
            i += length
        del buf[:i]
        s = self._stats
        self._stats = CodecStats(
            messages=s.messages + len(out),
            bytes_skipped=s.bytes_skipped + skipped,
            framing_errors=s.framing_errors + framing,
            unknown_messages=s.unknown_messages + unknown,
            rejected=s.rejected + rejected,
            refused_unsigned=s.refused_unsigned + unsigned,
            refused_bad_signature=s.refused_bad_signature + bad_sig,
            truncated=s.truncated,
        )
        return out

    def parse_datagram(self, data: bytes) -> list[MAVLinkMessage]:
        """Messages in one UDP datagram, which carries whole frames.

        ArduPilot sends MAVLink over UDP packetised (``mavlink_packetise``: whole frames per
        datagram), so a partial frame left at the end is noise: it is dropped here rather than
        left to swallow the next datagrams while waiting for its claimed length.
        """
        out = self.parse(data)
        if self._buf:
            self._buf.clear()
            s = self._stats
            self._stats = CodecStats(
                messages=s.messages,
                bytes_skipped=s.bytes_skipped,
                framing_errors=s.framing_errors,
                unknown_messages=s.unknown_messages,
                rejected=s.rejected,
                refused_unsigned=s.refused_unsigned,
                refused_bad_signature=s.refused_bad_signature,
                truncated=s.truncated + 1,
            )
        return out

    def reset(self) -> None:
        """Forget any partial frame (after a reconnect: a new stream starts)."""
        self._buf.clear()


_OK, _BAD, _UNKNOWN = 0, 1, 2


def message_id(frame: bytes | bytearray) -> int:
    """The message id of a whole MAVLink frame (1 or 2)."""
    if frame[0] == STX_V2:
        return frame[7] | (frame[8] << 8) | (frame[9] << 16)
    return frame[5]


def _decode(mav: Any, frame: bytearray) -> MAVLinkMessage:
    """``mav.decode(frame)``, refusing a message id the dialect lacks (pymavlink returns
    those as ``MAVLink_unknown`` without a CRC it could check)."""
    msg_id = message_id(frame)
    if msg_id not in mavlink2.mavlink_map:
        raise ValueError(f"unknown message id {msg_id}")
    return mav.decode(frame)


def _frame_ids(frame: bytearray) -> tuple[int, int, int]:
    """(system id, component id, message id) of a whole frame."""
    if frame[0] == STX_V2:
        return frame[5], frame[6], message_id(frame)
    return frame[3], frame[4], message_id(frame)


def _next_stx(buf: bytearray, start: int) -> int:
    """Index of the next start marker at or after ``start``, -1 if none."""
    v2 = buf.find(STX_V2, start)
    v1 = buf.find(STX_V1, start, v2 if v2 >= 0 else len(buf))
    return v1 if v1 >= 0 else v2


def _frame_length(buf: bytearray, i: int) -> int | None:
    """Total length of the frame starting at ``buf[i]``: None if the header is not all here yet,
    -1 if the header is impossible (unknown incompatibility flags)."""
    have = len(buf) - i
    if buf[i] == STX_V2:
        if have < 3:
            return None
        payload_len, incompat = buf[i + 1], buf[i + 2]
        if incompat & ~_IFLAG_SIGNED:
            return -1
        sig = _SIGNATURE_LEN if incompat & _IFLAG_SIGNED else 0
        return _HEADER_LEN_V2 + payload_len + _CRC_LEN + sig
    if have < 2:
        return None
    return _HEADER_LEN_V1 + buf[i + 1] + _CRC_LEN


def _check_frame(frame: bytearray) -> int:
    """_OK if the CRC (with the message's CRC_EXTRA) matches, _BAD if not, _UNKNOWN if the
    message id is not in the dialect (its CRC_EXTRA, hence its CRC, cannot be checked)."""
    header_len = _HEADER_LEN_V2 if frame[0] == STX_V2 else _HEADER_LEN_V1
    msg_type = mavlink2.mavlink_map.get(message_id(frame))
    if msg_type is None:
        return _UNKNOWN
    end = header_len + frame[1]
    crc = mavlink2.x25crc(frame[1:end])
    crc.accumulate(bytes((msg_type.crc_extra,)))
    return _OK if crc.crc == (frame[end] | (frame[end + 1] << 8)) else _BAD
