"""The parameter protocol (PARAM_REQUEST_LIST, PARAM_REQUEST_READ, PARAM_SET) and what a
changed parameter does to the vehicle."""

from __future__ import annotations

from typing import Any

from sitl import messages as mb
from sitl.autopilot import Autopilot, Clock, Kinematics, Outbox
from sitl.handlers.base import Src
from sitl.params import decode_param_id

#: Parameters that change the flight model's envelope (``Autopilot.write_envelope``).
ENVELOPE_PARAMS = frozenset(
    {
        "SIM_SPEED_MIN",
        "SIM_SPEED_MAX",
        "SIM_ACCEL_MAX",
        "SIM_DECEL_MAX",
        "SIM_YAW_RATE",
        "SIM_PTCH_RATE",
        "SIM_SPD_HGT",
        "SIM_ROLL_ZETA",
        "SIM_SPD_OMEGA",
        "SIM_SPD_ZETA",
        "SIM_EAS2TAS",
        "PTCH_LIM_MAX_DEG",
        "PTCH_LIM_MIN_DEG",
        "ROLL_LIMIT_DEG",
        "GUIDED_P",
        "TECS_CLMB_MAX",
        "TECS_SINK_MAX",
        "NAVL1_PERIOD",
        "NAVL1_DAMPING",
        "AIRSPEED_CRUISE",
        "RLL2SRV_TCONST",
        "TECS_TIME_CONST",
    }
)


def _param_msg(ap: Autopilot, index: int) -> Any:
    entry = ap.params.at(index)
    assert entry is not None
    spec, value = entry
    return mb.param_value(spec.name, value, int(spec.ptype), len(ap.params), index)


def on_param_request_list(
    ap: Autopilot, msg: Any, src: Src, kin: Kinematics, clock: Clock, out: Outbox
) -> None:
    out.reply.extend(_param_msg(ap, k) for k in range(len(ap.params)))


def on_param_request_read(
    ap: Autopilot, msg: Any, src: Src, kin: Kinematics, clock: Clock, out: Outbox
) -> None:
    if msg.param_index >= 0:
        if ap.params.at(msg.param_index) is not None:
            out.reply.append(_param_msg(ap, msg.param_index))
        return
    name = decode_param_id(msg.param_id)
    if name in ap.params:
        out.reply.append(_param_msg(ap, ap.params.index_of(name)))


def on_param_set(
    ap: Autopilot, msg: Any, src: Src, kin: Kinematics, clock: Clock, out: Outbox
) -> None:
    name = decode_param_id(msg.param_id)
    if name not in ap.params:
        return  # ArduPilot ignores unknown parameters
    if ap.params.set(name, float(msg.param_value)):
        apply_param(ap, name, clock)
        out.broadcast.append(_param_msg(ap, ap.params.index_of(name)))
    else:
        out.reply.append(_param_msg(ap, ap.params.index_of(name)))


def apply_param(ap: Autopilot, name: str, clock: Clock) -> None:
    """Side effects of a parameter change."""
    value = ap.params[name]
    if name in ENVELOPE_PARAMS:
        ap.envelope_dirty = True
        ap.guidance_dirty = True  # the speed demand is scaled by SIM_EAS2TAS
    elif name.startswith("AIRSPEED") or name == "WP_LOITER_RAD":
        ap.guidance_dirty = True
    elif name == "SIM_GPS_NOISE":
        ap.faults.noise_m = value
    elif name == "SIM_LINK_LOSS":
        ap.faults.loss_pct = value
    elif name == "SIM_LINK_DELAY":
        ap.faults.latency_ms = value
    elif name == "SIM_LINK_CUT" and value > 0:
        ap.faults.add_cut(clock.sim_s, value)
    elif name == "SIM_KILL" and value >= 1:
        ap.faults.dead = True
        ap.guidance_dirty = True
    elif name == "SIM_CMD_IGNORE":
        ap.faults.ignore_from_s = clock.sim_s if value >= 1 else None
