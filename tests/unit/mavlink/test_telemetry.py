"""Telemetry decoding with messages built (and put through the wire) by pymavlink."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from gcs_ppf.mavlink.ardupilot import PlaneMode
from gcs_ppf.mavlink.codec import Codec, MAVLinkMessage
from gcs_ppf.mavlink.telemetry import VehicleTelemetry, apply


def _wire(msg: MAVLinkMessage, system: int = 2, component: int = 1) -> MAVLinkMessage:
    """``msg`` as a receiver sees it: encoded by the vehicle, decoded by the ground station."""
    (decoded,) = Codec().parse(Codec(system, component).encode(msg))
    return decoded


def _heartbeat(custom_mode: int = 15, base_mode: int = 128 | 1) -> MAVLinkMessage:
    return _wire(mavlink2.MAVLink_heartbeat_message(1, 3, base_mode, custom_mode, 4, 3))


def test_heartbeat_starts_a_record() -> None:
    tel = apply(None, _heartbeat(), 10.0)
    assert (tel.system_id, tel.component_id) == (2, 1)
    assert (tel.mav_type, tel.autopilot) == (1, 3)
    assert tel.custom_mode == 15
    assert tel.mode is PlaneMode.GUIDED
    assert tel.mode_name == "GUIDED"
    assert tel.armed
    assert tel.system_status == 4
    assert tel.last_heartbeat_s == 10.0
    assert tel.last_update_s == 10.0
    assert tel.lat_deg is None


def test_unknown_custom_mode_keeps_the_raw_number() -> None:
    tel = apply(None, _heartbeat(custom_mode=99, base_mode=1), 0.0)
    assert tel.mode is None
    assert tel.custom_mode == 99
    assert tel.mode_name == "UNKNOWN(99)"
    assert not tel.armed


def test_global_position_int_units() -> None:
    tel = apply(None, _heartbeat(), 0.0)
    msg = mavlink2.MAVLink_global_position_int_message(
        123456, 473977420, -85455940, 788500, 300250, 2500, -120, 30, 9050
    )
    tel = apply(tel, _wire(msg), 1.0)
    assert tel.lat_deg == pytest.approx(47.397742, abs=1e-9)
    assert tel.lon_deg == pytest.approx(-8.545594, abs=1e-9)
    assert tel.alt_amsl_m == pytest.approx(788.5)
    assert tel.relative_alt_m == pytest.approx(300.25)
    assert (tel.vn_m_s, tel.ve_m_s, tel.vd_m_s) == pytest.approx((25.0, -1.2, 0.3))
    assert tel.heading_deg == pytest.approx(90.5)
    assert tel.time_boot_ms == 123456
    assert tel.last_update_s == 1.0
    assert tel.position_received_s == 1.0
    assert tel.last_heartbeat_s == 0.0
    tel = apply(tel, _wire(mavlink2.MAVLink_attitude_message(123500, 0, 0, 0, 0, 0, 0)), 1.05)
    assert tel.position_received_s == 1.0  # only a position moves it


def test_unknown_heading_is_none() -> None:
    msg = mavlink2.MAVLink_global_position_int_message(
        1, 473977420, 85455940, 0, 0, 0, 0, 0, 0xFFFF
    )
    tel = apply(None, _wire(msg), 0.0)
    assert tel.lat_deg is not None
    assert tel.heading_deg is None


def test_a_position_about_0_0_is_no_position() -> None:
    """ArduPlane 4.7 streams GLOBAL_POSITION_INT about 0°, 0° before its EKF has a
    position (as recorded from its SITL): three vehicles waiting for their GPS read
    11,761 km from their starts."""
    tel = apply(None, _heartbeat(), 0.0)
    nowhere = mavlink2.MAVLink_global_position_int_message(5000, 3003, -696, 100, 100, 0, 0, 0, 0)
    tel = apply(tel, _wire(nowhere), 1.0)
    assert (tel.lat_deg, tel.lon_deg, tel.position_received_s) == (None, None, None)
    assert tel.relative_alt_m == pytest.approx(0.1)  # on the runway: the barometer's height
    here = mavlink2.MAVLink_global_position_int_message(6000, 473977420, 85455940, 0, 0, 0, 0, 0, 0)
    assert apply(tel, _wire(here), 2.0).lat_deg == pytest.approx(47.397742)


def test_attitude_vfr_hud_and_system_time() -> None:
    tel = apply(None, _heartbeat(), 0.0)
    tel = apply(tel, _wire(mavlink2.MAVLink_attitude_message(2000, 0.1, -0.2, 3.0, 0, 0, 0)), 1.0)
    assert (tel.roll_rad, tel.pitch_rad, tel.yaw_rad) == pytest.approx((0.1, -0.2, 3.0))
    assert tel.time_boot_ms == 2000
    tel = apply(tel, _wire(mavlink2.MAVLink_vfr_hud_message(21.5, 23.0, 90, 55, 700.0, -1.5)), 2.0)
    assert (tel.airspeed_m_s, tel.groundspeed_m_s, tel.climb_m_s) == pytest.approx(
        (21.5, 23.0, -1.5)
    )
    assert tel.time_boot_ms == 2000  # VFR_HUD carries no time_boot_ms
    tel = apply(tel, _wire(mavlink2.MAVLink_system_time_message(0, 2500)), 3.0)
    assert tel.system_time_boot_ms == 2500
    assert tel.time_boot_ms == 2500
    assert tel.unix_time_us is None
    tel = apply(tel, _wire(mavlink2.MAVLink_system_time_message(1_700_000_000_000_000, 2600)), 4.0)
    assert tel.unix_time_us == 1_700_000_000_000_000


def test_time_boot_ms_follows_the_latest_message_even_after_a_reboot() -> None:
    tel = apply(None, _wire(mavlink2.MAVLink_attitude_message(90_000, 0, 0, 0, 0, 0, 0)), 0.0)
    tel = apply(tel, _wire(mavlink2.MAVLink_attitude_message(150, 0, 0, 0, 0, 0, 0)), 1.0)
    assert tel.time_boot_ms == 150


def test_command_acks_keep_the_last_per_command() -> None:
    tel = apply(None, _heartbeat(), 0.0)
    tel = apply(tel, _wire(mavlink2.MAVLink_command_ack_message(192, 4)), 1.0)
    tel = apply(tel, _wire(mavlink2.MAVLink_command_ack_message(176, 0)), 2.0)
    tel = apply(tel, _wire(mavlink2.MAVLink_command_ack_message(192, 0)), 3.0)
    assert [a.command for a in tel.command_acks] == [176, 192]
    ack = tel.ack(192)
    assert ack is not None
    assert (ack.result, ack.received_s) == (0, 3.0)
    assert tel.ack(400) is None


def _param(name: str, value: float) -> MAVLinkMessage:
    return _wire(mavlink2.MAVLink_param_value_message(name.encode(), value, 9, 1200, 7))


@pytest.mark.parametrize(
    ("hi", "lo", "scale"), [("PTCH_LIM_MAX_DEG", "PTCH_LIM_MIN_DEG", 1.0),
                            ("LIM_PITCH_MAX", "LIM_PITCH_MIN", 100.0)]
)  # fmt: skip
def test_pitch_limits_from_param_value_in_degrees_either_name(
    hi: str, lo: str, scale: float
) -> None:
    tel = apply(None, _heartbeat(), 0.0)
    tel = apply(tel, _param(hi, 20.0 * scale), 1.0)
    tel = apply(tel, _param(lo, -25.0 * scale), 2.0)
    assert tel.pitch_max_deg == pytest.approx(20.0)
    assert tel.pitch_min_deg == pytest.approx(-25.0)
    same = apply(tel, _param("WP_LOITER_RAD", 60.0), 3.0)  # other parameters: not kept
    assert same is tel
    assert apply(tel, _param(hi, math.nan), 4.0) is tel


def test_unknown_messages_and_other_senders_leave_the_record_unchanged() -> None:
    tel = apply(None, _heartbeat(), 0.0)
    status = mavlink2.MAVLink_statustext_message(6, b"hello")
    assert apply(tel, _wire(status), 5.0) is tel
    other_system = _wire(mavlink2.MAVLink_heartbeat_message(1, 3, 0, 12, 4, 3), system=9)
    assert apply(tel, other_system, 5.0) is tel
    camera = _wire(mavlink2.MAVLink_heartbeat_message(30, 8, 0, 0, 4, 3), component=100)
    assert apply(tel, camera, 5.0) is tel


def test_apply_returns_a_new_frozen_object_and_leaves_the_input_alone() -> None:
    tel = apply(None, _heartbeat(), 0.0)
    new = apply(tel, _heartbeat(custom_mode=12, base_mode=1), 1.0)
    assert new is not tel
    assert tel.mode is PlaneMode.GUIDED
    assert new.mode is PlaneMode.LOITER
    assert not new.armed
    with pytest.raises(dataclasses.FrozenInstanceError):
        new.armed = True  # type: ignore[misc]


def test_non_heartbeat_first_message_starts_an_empty_record() -> None:
    msg = mavlink2.MAVLink_vfr_hud_message(20.0, 20.0, 0, 0, 0.0, 0.0)
    tel = apply(None, _wire(msg, system=4), 0.0)
    assert isinstance(tel, VehicleTelemetry)
    assert tel.system_id == 4
    assert tel.custom_mode is None
    assert tel.mode_name is None
    assert tel.airspeed_m_s == 20.0
    assert not math.isnan(tel.airspeed_m_s)


def test_airframe_parameters_are_kept_with_when_they_arrived() -> None:
    tel = apply(None, _heartbeat(), 0.0)
    tel = apply(tel, _param("TECS_CLMB_MAX", 5.0), 1.0)
    tel = apply(tel, _param("GUIDED_P", 5000.0), 2.0)
    tel = apply(tel, _param("TECS_CLMB_MAX", 4.0), 3.0)  # changed: the latest is kept
    assert [p.name for p in tel.params] == ["GUIDED_P", "TECS_CLMB_MAX"]
    clmb = tel.param("TECS_CLMB_MAX")
    assert clmb is not None
    assert (clmb.value, clmb.received_s) == (4.0, 3.0)
    assert tel.param("ROLL_LIMIT_DEG") is None
    tel = apply(tel, _param("PTCH_LIM_MAX_DEG", 25.0), 4.0)  # a pitch limit: both places
    assert tel.pitch_max_deg == 25.0
    limit = tel.param("PTCH_LIM_MAX_DEG")
    assert limit is not None
    assert limit.value == 25.0


def _position(boot_ms: int, course_deg: float, speed_m_s: float = 200.0) -> MAVLinkMessage:
    c = math.radians(course_deg)
    vn, ve = speed_m_s * math.cos(c), speed_m_s * math.sin(c)
    return _wire(mavlink2.MAVLink_global_position_int_message(
        boot_ms, 473977420, 85455940, 788500, 300250, round(vn * 100), round(ve * 100), 0, 0
    ))  # fmt: skip


def test_the_course_rate_is_measured_from_successive_velocities_in_vehicle_time() -> None:
    """Turning right (clockwise) at 0.3 rad/s, a position every 100 ms of vehicle time: the
    smoothed rate converges on +0.3; a straight course brings it back to 0; positions
    more than 1 s apart (a gap) measure nothing."""
    tel = apply(None, _heartbeat(), 0.0)
    for k in range(30):
        tel = apply(tel, _position(1000 + 100 * k, math.degrees(0.03 * k)), 0.01 * k)
    assert tel.course_rate_rad_s == pytest.approx(0.3, rel=0.02)
    for k in range(30, 60):
        tel = apply(tel, _position(1000 + 100 * k, math.degrees(0.03 * 29)), 0.01 * k)
    assert tel.course_rate_rad_s == pytest.approx(0.0, abs=1e-3)
    tel = apply(tel, _position(20_000, 120.0), 1.0)
    assert tel.course_rate_rad_s == 0.0


def _climbing(boot_ms: int, vd_m_s: float) -> MAVLinkMessage:
    return _wire(mavlink2.MAVLink_global_position_int_message(
        boot_ms, 473977420, 85455940, 788500, 300250, 2500, 0, round(vd_m_s * 100), 0
    ))  # fmt: skip


def test_the_flight_path_is_the_vertical_speed_averaged_over_tecs_oscillations() -> None:
    """A ±3 m/s oscillation of the vertical speed with a 6 s period (ArduPlane's TECS in
    formation) about a 1 m/s climb: the average stays near the climb; a steady climb is
    followed; after a gap of more than a second the newest speed is taken as it is."""
    tel = apply(None, _heartbeat(), 0.0)
    means = []
    for k in range(600):  # 60 s at 10 Hz
        vd = -1.0 + 3.0 * math.sin(2.0 * math.pi * k * 0.1 / 6.0)
        tel = apply(tel, _climbing(1000 + 100 * k, vd), 0.01 * k)
        assert tel.vd_m_s == pytest.approx(vd, abs=0.01)
        if k >= 300:
            assert tel.vd_mean_m_s is not None
            means.append(tel.vd_mean_m_s)
    assert max(means) - min(means) < 0.5 * 6.0  # the swing attenuated by more than half
    assert float(np.mean(means)) == pytest.approx(-1.0, abs=0.1)
    for k in range(600, 800):
        tel = apply(tel, _climbing(1000 + 100 * k, -2.0), 0.01 * k)
    assert tel.vd_mean_m_s == pytest.approx(-2.0, abs=0.01)
    tel = apply(tel, _climbing(200_000, 4.0), 3.0)
    assert tel.vd_mean_m_s == 4.0


def _hud(airspeed: float, groundspeed: float) -> MAVLinkMessage:
    return _wire(mavlink2.MAVLink_vfr_hud_message(airspeed, groundspeed, 0, 50, 650.0, 0.0))


def test_the_airspeed_ratio_is_averaged_and_leaves_out_the_runway() -> None:
    """VFR_HUD's airspeed / groundspeed swung 0.915–0.98 with TECS's vertical oscillation
    (real ArduPlane, 27 m/s): averaged over 10 s it stays near its mean; samples on the
    runway (under 5 m/s over the ground) are left out; a gap of more than 2 s restarts it."""
    tel = apply(None, _heartbeat(), 0.0)
    tel = apply(tel, _hud(0.6, 0.1), 0.0)  # at rest: no ratio
    assert tel.speed_ratio_mean is None
    ratios = []
    for k in range(600):  # 60 s at 5 Hz of VFR_HUD, the vehicle's clock from ATTITUDE
        boot_ms = 1000 + 200 * k
        tel = apply(tel, _wire(mavlink2.MAVLink_attitude_message(boot_ms, 0, 0, 0, 0, 0, 0)), k)
        ratio = 0.9475 + 0.0325 * math.sin(2.0 * math.pi * k * 0.2 / 2.0)
        tel = apply(tel, _hud(27.0 * ratio, 27.0), k)
        if k >= 300:
            assert tel.speed_ratio_mean is not None
            ratios.append(tel.speed_ratio_mean)
    assert max(ratios) - min(ratios) < 0.1 * 0.065  # the swing down to a tenth
    assert float(np.mean(ratios)) == pytest.approx(0.9475, abs=0.002)
    before = tel.speed_ratio_mean
    tel = apply(tel, _hud(0.5, 0.2), 601)  # slowed to the ground: left out
    assert tel.speed_ratio_mean == before
    tel = apply(tel, _wire(mavlink2.MAVLink_attitude_message(200_000, 0, 0, 0, 0, 0, 0)), 602)
    tel = apply(tel, _hud(20.0, 25.0), 602)
    assert tel.speed_ratio_mean == pytest.approx(0.8)


def test_the_airspeed_ratio_is_taken_along_the_flight_path() -> None:
    """VFR_HUD's groundspeed is horizontal, the airspeed along the flight path: climbing at
    60° with no wind the two speeds are the same, not 2 : 1 (over the horizontal speed,
    a vehicle planned at 100 m/s was commanded 190 and sped up to 300)."""
    tel = apply(None, _heartbeat(), 0.0)
    climb = 100.0 * math.sin(math.radians(60.0))
    horizontal = 100.0 * math.cos(math.radians(60.0))
    msg = _wire(mavlink2.MAVLink_vfr_hud_message(100.0, horizontal, 0, 50, 650.0, climb))
    tel = apply(tel, msg, 0.0)
    assert tel.speed_ratio_mean == pytest.approx(1.0)


def _sys_status(present: int, health: int) -> MAVLinkMessage:
    return _wire(
        mavlink2.MAVLink_sys_status_message(
            present, present, health, 200, 12600, 1000, 90, 0, 0, 0, 0, 0, 0
        )
    )


def test_the_pre_arm_bit_of_sys_status_and_the_gps_fix() -> None:
    prearm = 1 << 28
    tel = apply(None, _heartbeat(), 1.0)
    assert tel.prearm_ok is None
    tel = apply(tel, _sys_status(0x3F, 0x3F), 2.0)  # a vehicle that does not report the bit
    assert tel.prearm_ok is None
    tel = apply(tel, _sys_status(0x3F | prearm, 0x3F), 3.0)  # ArduPilot, checks failing
    assert tel.prearm_ok is False
    tel = apply(tel, _sys_status(0x3F | prearm, 0x3F | prearm), 4.0)
    assert tel.prearm_ok is True
    gps = mavlink2.MAVLink_gps_raw_int_message(0, 2, 0, 0, 0, 65535, 65535, 0, 65535, 5)
    assert apply(tel, _wire(gps), 5.0).gps_fix_type == 2


def test_arming_reasons_from_statustext_newest_last_one_per_text() -> None:
    def text(t: str) -> MAVLinkMessage:
        return _wire(mavlink2.MAVLink_statustext_message(4, t.encode()))

    tel = apply(None, _heartbeat(), 1.0)
    tel = apply(tel, text("PreArm: AHRS: waiting for home"), 2.0)
    tel = apply(tel, text("Throttle armed"), 2.5)  # not a reason
    tel = apply(tel, text("PreArm: GPS 1: Bad fix"), 3.0)
    tel = apply(tel, text("PreArm: AHRS: waiting for home"), 4.0)
    tel = apply(tel, text("Arm: Throttle (RC3) is not neutral"), 5.0)
    assert [(r.text, r.received_s) for r in tel.arming_reasons] == [
        ("PreArm: GPS 1: Bad fix", 3.0),
        ("PreArm: AHRS: waiting for home", 4.0),
        ("Arm: Throttle (RC3) is not neutral", 5.0),
    ]
    from gcs_ppf.mavlink.telemetry import ARMING_REASONS_KEPT, recent_reasons

    assert recent_reasons(tel, 4.0) == [
        "PreArm: AHRS: waiting for home",
        "Arm: Throttle (RC3) is not neutral",
    ]
    for k in range(2 * ARMING_REASONS_KEPT):
        tel = apply(tel, text(f"PreArm: check {k}"), 10.0 + k)
    assert len(tel.arming_reasons) == ARMING_REASONS_KEPT
    assert tel.arming_reasons[-1].text == f"PreArm: check {2 * ARMING_REASONS_KEPT - 1}"


def test_home_position_is_kept_once_the_vehicle_has_one() -> None:
    def home(lat_e7: int, lon_e7: int, alt_mm: int) -> MAVLinkMessage:
        q = [1.0, 0.0, 0.0, 0.0]
        return _wire(
            mavlink2.MAVLink_home_position_message(lat_e7, lon_e7, alt_mm, 0, 0, 0, q, 0, 0, 0, 0)
        )

    tel = apply(None, _heartbeat(), 1.0)
    assert apply(tel, home(0, 0, 0), 2.0).home_lat_deg is None  # not yet: 0°, 0°
    tel = apply(tel, home(473977420, 85455940, 488_500), 3.0)
    assert (tel.home_lat_deg, tel.home_lon_deg) == pytest.approx((47.397742, 8.545594))
    assert tel.home_alt_amsl_m == pytest.approx(488.5)
