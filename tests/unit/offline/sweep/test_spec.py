"""Spec files: the feasible family's defaults, TOML and JSON, errors that name the field."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from gcs_ppf.offline.sweep.families import FAMILIES, FEASIBLE
from gcs_ppf.offline.sweep.spec import SceneSpec, SpecError, load_spec_file, parse_spec

TOML_SPEC = """
name = "big-v"
planner = { dt = 0.02, max_time = 120.0 }

[fleet]
wingmen = [6, 12]
slot_spacing_m = [80.0, 200.0]

[obstacles]
count = [2, 6]
radius_m = [100.0, 400.0]
speed_m_s = [0.0, 50.0]
"""


def test_the_defaults_are_the_feasible_family() -> None:
    assert SceneSpec() == FEASIBLE
    assert FEASIBLE.planner.max_time == 90.0
    assert FEASIBLE.initial_speed_m_s == (FEASIBLE.limits.v_min, FEASIBLE.limits.v_max)
    assert set(FAMILIES) == {"feasible", "dense", "moving", "close", "zones", "pockets"}


def test_zones_that_would_move_are_refused_naming_the_field() -> None:
    with pytest.raises(SpecError) as err:
        parse_spec({"zones": {"shape": "pocket"}, "obstacles": {"speed_m_s": [0.0, 20.0]}})
    assert err.value.field == "zones"
    with pytest.raises(SpecError) as err:
        parse_spec({"zones": {"shape": "donut"}})
    assert err.value.field.startswith("zones.shape")


def test_a_toml_spec_changes_only_what_it_states(tmp_path: Path) -> None:
    path = tmp_path / "big.toml"
    path.write_text(TOML_SPEC)
    spec = load_spec_file(path)
    assert spec.name == "big-v"
    assert spec.planner.dt == 0.02
    assert spec.fleet.wingmen == (6, 12)
    assert spec.obstacles.speed_m_s == (0.0, 50.0)
    assert spec.fleet.start_gap_m == FEASIBLE.fleet.start_gap_m
    assert spec.limits == FEASIBLE.limits


def test_a_json_spec_is_named_after_its_file(tmp_path: Path) -> None:
    path = tmp_path / "few.json"
    path.write_text(json.dumps({"fleet": {"wingmen": [1, 2]}}))
    spec = load_spec_file(path)
    assert spec.name == "few"
    assert spec.fleet.wingmen == (1, 2)


@pytest.mark.parametrize(
    ("raw", "field", "words"),
    [
        ({"fleet": {"wingman": [1, 2]}}, "fleet.wingman", "unknown key"),
        ({"obstacles": {"radius_m": [700, 30]}}, "obstacles.radius_m", "low 700 exceeds high 30"),
        ({"fleet": {"wingmen": [-1, 2]}}, "fleet.wingmen[0]", "greater than or equal to 0"),
        ({"fleet": {"wingmen": [0, 300]}}, "fleet.wingmen", "at most 253"),
        ({"fleet": {"start_gap_m": 20.0}}, "fleet.start_gap_m", "safe_distance_uav"),
        ({"fleet": {"slot_spacing_m": [20.0, 100.0]}}, "fleet.slot_spacing_m", "closer than"),
        ({"fleet": {"speed_m_s": [50.0, 100.0]}}, "fleet.speed_m_s", "limits.v_min"),
        ({"fleet": {"pitch_rad": [-2.0, 0.0]}}, "fleet.pitch_rad", "[-π/2, π/2]"),
        ({"obstacles": {"radius_m": [0.0, 10.0]}}, "obstacles.radius_m", "positive"),
        ({"obstacles": {"speed_m_s": [-5.0, 10.0]}}, "obstacles.speed_m_s", "negative"),
        ({"obstacles": {"placement": "packed"}}, "obstacles.placement", "'apart' or 'overlapping'"),
        ({"planner": {"dt": 0.0}}, "planner.dt", "greater than 0"),
        ({"limits": {"v_min": 400.0}}, "limits.v_min", "must not exceed limits.v_max"),
        ({"target_box": {"center_m": [0, 0, 0]}}, "target_box.half_size_m", "required"),
        ({"ground": {"depth_m": [1.0, float("nan")]}}, "ground.depth_m[1]", "finite"),
    ],
)
def test_a_bad_spec_names_its_field(raw: dict[str, object], field: str, words: str) -> None:
    with pytest.raises(SpecError) as caught:
        parse_spec(raw)
    assert caught.value.field == field
    assert words in caught.value.message


def test_files_that_are_not_specs_say_so(tmp_path: Path) -> None:
    bad_toml = tmp_path / "bad.toml"
    bad_toml.write_text("name = \n")
    with pytest.raises(SpecError, match="spec: not valid TOML"):
        load_spec_file(bad_toml)
    a_list = tmp_path / "list.json"
    a_list.write_text("[1, 2]")
    with pytest.raises(SpecError, match="spec: must be a table"):
        load_spec_file(a_list)
    with pytest.raises(SpecError, match="cannot read"):
        load_spec_file(tmp_path / "missing.toml")
