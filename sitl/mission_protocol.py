"""Vehicle side of the MAVLink mission protocol, sans I/O.

Events in (decoded fields of MISSION_COUNT, MISSION_ITEM_INT, MISSION_REQUEST_LIST, …, and
the time), messages out. Follows ArduPilot's ``MissionItemProtocol``: item 0 is home (a
download answers it from the current home, an upload's item 0 is stored but does not move
home); one upload at a time, owned by the (sysid, compid) that sent MISSION_COUNT; items must
arrive in order (another sequence number → MISSION_ACK INVALID_SEQUENCE, the upload goes on);
an item that cannot be stored ends the upload with its error; the vehicle asks again for an
item after ``RESEND_S`` of silence and gives up after ``UPLOAD_TIMEOUT_S``
(MISSION_ACK OPERATION_CANCELLED). One server per list: the mission (its item 0 home), and
the fence (``sitl.fence``: no home item, its own items); the rally list is empty and cannot
be filled.
Timers run on the link's (wall) clock: protocol timeouts are properties of the link, not of
simulated time.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from enum import Enum

from pymavlink.dialects.v20 import ardupilotmega as mavlink

from gcs_ppf.mavlink.enums import (
    MAV_CMD_DO_CHANGE_SPEED,
    MAV_CMD_DO_JUMP,
    MAV_CMD_NAV_LAND,
    MAV_CMD_NAV_LOITER_TIME,
    MAV_CMD_NAV_LOITER_TURNS,
    MAV_CMD_NAV_LOITER_UNLIM,
    MAV_CMD_NAV_RETURN_TO_LAUNCH,
    MAV_CMD_NAV_TAKEOFF,
    MAV_CMD_NAV_WAYPOINT,
    MAV_MISSION_ACCEPTED,
    MAV_MISSION_DENIED,
    MAV_MISSION_ERROR,
    MAV_MISSION_INVALID_PARAM1,
    MAV_MISSION_INVALID_PARAM5_X,
    MAV_MISSION_INVALID_PARAM6_Y,
    MAV_MISSION_INVALID_PARAM7,
    MAV_MISSION_INVALID_SEQUENCE,
    MAV_MISSION_NO_SPACE,
    MAV_MISSION_OPERATION_CANCELLED,
    MAV_MISSION_UNSUPPORTED,
    MAV_MISSION_UNSUPPORTED_FRAME,
)
from sitl.messages import Message

MAX_ITEMS = 724  # ArduPilot's mission storage on a typical board
RESEND_S = 1.0
UPLOAD_TIMEOUT_S = 8.0

MISSION_TYPE_MISSION = 0
MISSION_TYPE_FENCE = 1
MISSION_TYPE_RALLY = 2
MISSION_TYPE_ALL = 255

# MAV_MISSION_RESULT (MAVLink common dialect).


#: Navigation commands with a location, and which of param1–4 may be NaN (ArduPilot's
#: ``sanity_check_params``: param4, the yaw, for WAYPOINT, LAND and TAKEOFF).
NAV_WITH_LOCATION = {
    MAV_CMD_NAV_WAYPOINT: (3,),
    MAV_CMD_NAV_LOITER_UNLIM: (),
    MAV_CMD_NAV_LOITER_TURNS: (),
    MAV_CMD_NAV_LOITER_TIME: (),
    MAV_CMD_NAV_LAND: (3,),
    MAV_CMD_NAV_TAKEOFF: (3,),
}
NAV_COMMANDS = frozenset(NAV_WITH_LOCATION) | {MAV_CMD_NAV_RETURN_TO_LAUNCH}
SUPPORTED_COMMANDS = NAV_COMMANDS | {MAV_CMD_DO_JUMP, MAV_CMD_DO_CHANGE_SPEED}

GLOBAL_FRAMES = frozenset({0, 3, 5, 6, 10, 11})
RELATIVE_FRAMES = frozenset({3, 6, 10, 11})


@dataclass(frozen=True, slots=True)
class MissionItem:
    """One stored mission item, in MISSION_ITEM_INT units (x/y degE7, z metres)."""

    frame: int
    command: int
    current: int
    autocontinue: int
    param1: float
    param2: float
    param3: float
    param4: float
    x: int
    y: int
    z: float


def item_from_message(msg: Message) -> MissionItem:
    """A MissionItem from a MISSION_ITEM_INT or (deprecated, float) MISSION_ITEM."""
    x, y = msg.x, msg.y
    if msg.get_type() == "MISSION_ITEM":
        if msg.frame in GLOBAL_FRAMES and math.isfinite(x) and math.isfinite(y):
            x, y = round(x * 1e7), round(y * 1e7)
        else:
            x = round(x) if math.isfinite(x) else 0
            y = round(y) if math.isfinite(y) else 0
    return MissionItem(
        int(msg.frame),
        int(msg.command),
        int(msg.current),
        int(msg.autocontinue),
        float(msg.param1),
        float(msg.param2),
        float(msg.param3),
        float(msg.param4),
        int(x),
        int(y),
        float(msg.z),
    )


def validate_item(item: MissionItem) -> int:
    """MAV_MISSION_RESULT of storing ``item`` (ACCEPTED or the reason it cannot be stored)."""
    if item.command not in SUPPORTED_COMMANDS:
        return MAV_MISSION_UNSUPPORTED
    params = (item.param1, item.param2, item.param3, item.param4)
    nan_ok = NAV_WITH_LOCATION.get(item.command, ())
    for k, p in enumerate(params):
        if not math.isfinite(p) and k not in nan_ok:
            return MAV_MISSION_INVALID_PARAM1 + k
    if item.command in NAV_WITH_LOCATION:
        if item.frame not in GLOBAL_FRAMES:
            return MAV_MISSION_UNSUPPORTED_FRAME
        if not -900_000_000 <= item.x <= 900_000_000:
            return MAV_MISSION_INVALID_PARAM5_X
        if not -1_800_000_000 <= item.y <= 1_800_000_000:
            return MAV_MISSION_INVALID_PARAM6_Y
        if not math.isfinite(item.z) or abs(item.z) > 100_000:
            return MAV_MISSION_INVALID_PARAM7
    return MAV_MISSION_ACCEPTED


class Transfer(Enum):
    """State of the vehicle's side of the protocol."""

    IDLE = "idle"
    """No upload in progress: downloads, clears and new uploads are served."""
    RECEIVING = "receiving"
    """An upload is in progress: items are requested from its owner in order."""


@dataclass
class Result:
    """What an event produced: messages to send back, and whether the mission changed."""

    replies: list[Message] = field(default_factory=list)
    mission_changed: bool = False


@dataclass
class MissionServer:
    """A stored list and its upload state machine: the mission (``items[0]`` is the home
    slot) or, with ``mission_type`` MISSION_TYPE_FENCE, the fence (``validate`` checks its
    items)."""

    mission_type: int = MISSION_TYPE_MISSION
    validate: Callable[[MissionItem], int] = field(default=validate_item, repr=False)
    items: list[MissionItem] = field(default_factory=list)
    state: Transfer = Transfer.IDLE
    _owner: tuple[int, int] = (0, 0)
    _expected: int = 0
    _count: int = 0
    _pending: list[MissionItem] = field(default_factory=list)
    _last_rx_s: float = 0.0
    _last_request_s: float = 0.0

    # ---- helpers -------------------------------------------------------------------------
    @property
    def count(self) -> int:
        """MISSION_COUNT of a download: home plus the stored items (at least 1); a fence's
        items alone."""
        if self.mission_type != MISSION_TYPE_MISSION:
            return len(self.items)
        return max(1, len(self.items))

    def _ack(self, to: tuple[int, int], result: int, mission_type: int | None = None) -> Message:
        kind = self.mission_type if mission_type is None else mission_type
        return mavlink.MAVLink_mission_ack_message(to[0], to[1], result, kind)

    def _request(self) -> Message:
        return mavlink.MAVLink_mission_request_int_message(
            self._owner[0], self._owner[1], self._expected, self.mission_type
        )

    def _finish_upload(self) -> None:
        self.state = Transfer.IDLE
        self._pending = []

    # ---- events --------------------------------------------------------------------------
    def on_count(self, src: tuple[int, int], count: int, mission_type: int, now_s: float) -> Result:
        if mission_type != self.mission_type:
            result = MAV_MISSION_ACCEPTED if count == 0 else MAV_MISSION_UNSUPPORTED
            return Result([self._ack(src, result, mission_type)])
        if self.state == Transfer.RECEIVING and src != self._owner:
            return Result([self._ack(src, MAV_MISSION_DENIED)])
        self._finish_upload()
        if count > MAX_ITEMS:
            return Result([self._ack(src, MAV_MISSION_NO_SPACE)])
        if count == 0:
            self.items = []
            return Result([self._ack(src, MAV_MISSION_ACCEPTED)], mission_changed=True)
        self.state = Transfer.RECEIVING
        self._owner, self._count, self._expected = src, count, 0
        self._last_rx_s = self._last_request_s = now_s
        return Result([self._request()])

    def on_item(
        self, src: tuple[int, int], seq: int, item: MissionItem, mission_type: int, now_s: float
    ) -> Result:
        if mission_type != self.mission_type:
            return Result([self._ack(src, MAV_MISSION_UNSUPPORTED, mission_type)])
        if self.state != Transfer.RECEIVING:
            return Result([self._ack(src, MAV_MISSION_ERROR)])
        if seq != self._expected:
            return Result([self._ack(src, MAV_MISSION_INVALID_SEQUENCE)])
        if src != self._owner:
            return Result([self._ack(src, MAV_MISSION_DENIED)])
        home = seq == 0 and self.mission_type == MISSION_TYPE_MISSION
        result = MAV_MISSION_ACCEPTED if home else self.validate(item)
        if result != MAV_MISSION_ACCEPTED:
            self._finish_upload()
            return Result([self._ack(src, result)])
        self._pending.append(item)
        self._expected += 1
        self._last_rx_s = self._last_request_s = now_s
        if self._expected >= self._count:
            self.items = self._pending
            self._finish_upload()
            return Result([self._ack(src, MAV_MISSION_ACCEPTED)], mission_changed=True)
        return Result([self._request()])

    def on_request_list(self, src: tuple[int, int], mission_type: int) -> Result:
        if self.state == Transfer.RECEIVING:
            return Result([self._ack(src, MAV_MISSION_DENIED, mission_type)])
        count = self.count if mission_type == self.mission_type else 0
        return Result([mavlink.MAVLink_mission_count_message(src[0], src[1], count, mission_type)])

    def on_request(
        self, src: tuple[int, int], seq: int, mission_type: int, home: MissionItem, as_int: bool
    ) -> Result:
        """MISSION_REQUEST_INT (``as_int``) or the deprecated MISSION_REQUEST."""
        if self.state == Transfer.RECEIVING:
            return Result([self._ack(src, MAV_MISSION_DENIED, mission_type)])
        if mission_type != self.mission_type or not 0 <= seq < self.count:
            count = self.count if mission_type == self.mission_type else 0
            return Result(
                [
                    mavlink.MAVLink_mission_count_message(src[0], src[1], count, mission_type),
                    self._ack(src, MAV_MISSION_INVALID_SEQUENCE, mission_type),
                ]
            )
        it = home if seq == 0 and self.mission_type == MISSION_TYPE_MISSION else self.items[seq]
        if as_int:
            msg = mavlink.MAVLink_mission_item_int_message(
                src[0],
                src[1],
                seq,
                it.frame,
                it.command,
                0,
                it.autocontinue,
                it.param1,
                it.param2,
                it.param3,
                it.param4,
                it.x,
                it.y,
                it.z,
                self.mission_type,
            )
        else:
            scale = 1e-7 if it.frame in GLOBAL_FRAMES else 1.0
            msg = mavlink.MAVLink_mission_item_message(
                src[0],
                src[1],
                seq,
                it.frame,
                it.command,
                0,
                it.autocontinue,
                it.param1,
                it.param2,
                it.param3,
                it.param4,
                it.x * scale,
                it.y * scale,
                it.z,
                self.mission_type,
            )
        return Result([msg])

    def on_clear_all(self, src: tuple[int, int], mission_type: int) -> Result:
        if self.state == Transfer.RECEIVING:
            if src != self._owner:
                return Result([self._ack(src, MAV_MISSION_DENIED, mission_type)])
            self._finish_upload()
        if mission_type in (self.mission_type, MISSION_TYPE_ALL):
            self.items = []
            return Result([self._ack(src, MAV_MISSION_ACCEPTED, mission_type)], True)
        return Result([self._ack(src, MAV_MISSION_ACCEPTED, mission_type)])

    def tick(self, now_s: float) -> Result:
        """Re-request a late item, or give the upload up after UPLOAD_TIMEOUT_S."""
        if self.state != Transfer.RECEIVING:
            return Result()
        if now_s - self._last_rx_s > UPLOAD_TIMEOUT_S:
            owner = self._owner
            self._finish_upload()
            return Result([self._ack(owner, MAV_MISSION_OPERATION_CANCELLED)])
        if now_s - self._last_request_s > RESEND_S:
            self._last_request_s = now_s
            return Result([self._request()])
        return Result()
