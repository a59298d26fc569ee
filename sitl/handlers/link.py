"""The link's housekeeping: the GCS's HEARTBEAT, TIMESYNC, and FTP (refused: no files)."""

from __future__ import annotations

from typing import Any

from gcs_ppf.mavlink.enums import MAV_TYPE_GCS
from sitl import messages as mb
from sitl.autopilot import Autopilot, Clock, Kinematics, Outbox
from sitl.handlers.base import Src


def on_heartbeat(
    ap: Autopilot, msg: Any, src: Src, kin: Kinematics, clock: Clock, out: Outbox
) -> None:
    if msg.type == MAV_TYPE_GCS and src[0] == int(ap.params["SYSID_MYGCS"]):
        ap.last_gcs_heartbeat_s = clock.sim_s


def on_timesync(
    ap: Autopilot, msg: Any, src: Src, kin: Kinematics, clock: Clock, out: Outbox
) -> None:
    """As ArduPilot's ``handle_timesync``: a request (tc1 = 0) is answered with tc1 = our
    clock in ns and ts1 echoed; an answer is ignored."""
    if msg.tc1 == 0:
        out.reply.append(mb.timesync(int(clock.sim_s * 1e9), int(msg.ts1)))


def on_ftp(ap: Autopilot, msg: Any, src: Src, kin: Kinematics, clock: Clock, out: Outbox) -> None:
    out.reply.append(mb.ftp_nak_file_not_found(bytes(msg.payload), src[0], src[1]))
