"""ArduPlane mode numbers against the ardupilotmega dialect's PLANE_MODE enum."""

from __future__ import annotations

from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from gcs_ppf.mavlink.ardupilot import PlaneMode, is_armed, mode_name, plane_mode


def test_modes_of_conventions_section_5() -> None:
    expected = {"MANUAL": 0, "CIRCLE": 1, "AUTO": 10, "RTL": 11, "LOITER": 12, "TAKEOFF": 13}
    expected["GUIDED"] = 15
    assert {name: int(PlaneMode[name]) for name in expected} == expected


def test_every_dialect_plane_mode_has_the_same_number() -> None:
    dialect = {
        name.removeprefix("PLANE_MODE_"): getattr(mavlink2, name)
        for name in dir(mavlink2)
        if name.startswith("PLANE_MODE_") and name != "PLANE_MODE_ENUM_END"
    }
    dialect["INITIALISING"] = dialect.pop("INITIALIZING")  # ArduPlane's mode.h spelling
    assert {m.name: int(m) for m in PlaneMode} == dialect


def test_mode_name_and_unknown_numbers() -> None:
    assert mode_name(15) == "GUIDED"
    assert mode_name(5) == "FLY_BY_WIRE_A"
    assert mode_name(9) == "UNKNOWN(9)"
    assert plane_mode(9) is None
    assert plane_mode(12) is PlaneMode.LOITER


def test_is_armed_reads_the_safety_armed_bit_only() -> None:
    assert is_armed(128 | 1)
    assert is_armed(0xFF)
    assert not is_armed(0x7F)
    assert not is_armed(0)
