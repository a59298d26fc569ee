"""The formation report: time to form, share in formation, errors while formed, from the
observer's tracks alone."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from gcs_ppf.geodesy import enu_to_geodetic_many
from gcs_ppf.mission import Mission, load_mission_file
from gcs_ppf.tools.campaign import ROOT
from gcs_ppf.tools.formation_report import (
    axes_report,
    formation_flown,
    observed_tracks,
    report,
    run_turns,
    takeoff_ended_s,
    turns_report,
)


def _line_east(t: np.ndarray, offset: tuple[float, float, float]) -> np.ndarray:
    """A track [t, x, y, z, height] flying east at 100 m/s at 300 m, shifted by ``offset``."""
    x, y, z = 100.0 * t + offset[0], np.full_like(t, offset[1]), np.full_like(t, 300.0 + offset[2])
    return np.column_stack([t, x, y, z, z])


def _flown(mission: Mission, t: np.ndarray, off_m: np.ndarray) -> dict[int, np.ndarray]:
    """The leader east, every wingman on its slot but the first, ``off_m`` [T] to its left."""
    tracks = {mission.leader.id: _line_east(t, (0.0, 0.0, 0.0))}
    for k, w in enumerate(mission.wingmen):
        assert w.slot is not None
        x, y, z = w.slot
        track = _line_east(t, (x, y, z))
        if k == 0:
            track[:, 2] += off_m
        tracks[w.id] = track
    return tracks


def _write_observer(
    where: Path,
    mission: Mission,
    t: np.ndarray,
    tracks: dict[int, np.ndarray],
    modes: list[list[int]] | None = None,
) -> None:
    """``observer.json`` as the campaign stores it (wall, boot ms, lat, lon, alt, height;
    each vehicle's ``modes``, [boot ms, mode] rows, if given)."""
    raw: dict[str, object] = {"end_wall": 0.0}
    for vid, track in tracks.items():
        lat, lon, alt = enu_to_geodetic_many(track[:, 1:4], mission.origin)
        rows = np.column_stack([np.zeros_like(t), np.round(1000 * t), lat, lon, alt, track[:, 4]])
        raw[str(vid)] = {"pos": rows.tolist(), "modes": modes or []}
    (where / "observer.json").write_text(json.dumps(raw))


def test_the_formation_forms_when_the_last_wingman_reaches_its_slot() -> None:
    """Off by 30 m until 20 s, on its slot after, but 15 m off for 5 s from 30 s: formed
    15 s into a run from 5 s, in formation 10 of the 15 s after it, the longest hold 10 s,
    the errors while formed those of the slots (0 m)."""
    mission = load_mission_file(ROOT / "examples" / "paper_table3.json")
    t = np.arange(0.0, 40.0, 0.05)
    off = np.where(t < 20.0, 30.0, np.where((t >= 30.0) & (t < 35.0), 15.0, 0.0))
    f = formation_flown(mission, _flown(mission, t, off), 5.0, 40.0)
    assert f is not None
    assert f.formed_after_s == pytest.approx(15.0, abs=0.6)
    assert f.in_formation_share == pytest.approx(15.0 / 20.0, abs=0.05)
    assert f.held_s == pytest.approx(10.0, abs=0.6)
    assert f.formed_rms_m is not None
    assert f.formed_rms_m < 1.0
    never = formation_flown(mission, _flown(mission, t, np.full_like(t, 30.0)), 5.0, 40.0)
    assert never is not None
    assert never.formed_after_s is None
    assert never.in_formation_share == 0.0


def test_a_campaign_directory_is_reported_from_the_observers_samples(tmp_path: Path) -> None:
    """The samples as the campaign stores them (wall, boot ms, lat, lon, alt, height)."""
    path = ROOT / "examples" / "paper_table3.json"
    mission = load_mission_file(path)
    t = np.arange(0.0, 40.0, 0.1)
    tracks = _flown(mission, t, np.where(t < 20.0, 30.0, 0.0))
    _write_observer(tmp_path, mission, t, tracks)
    back = observed_tracks(tmp_path / "observer.json", mission)
    assert np.allclose(
        back[mission.leader.id][:, 1:4], tracks[mission.leader.id][:, 1:4], atol=0.05
    )
    rec = {"mission": mission.name, "mission_file": str(path), "condition": "f",
           "dir": str(tmp_path), "window_s": [5.0, 70.0]}  # fmt: skip
    table = report([rec])
    row = table.splitlines()[1].split()
    assert row[:4] == [mission.name, "f", "1", "1"]
    assert row[4].split("/")[1] == "15.0"  # formed 15 s after the run's start


def test_the_axes_say_which_way_a_wingman_misses_its_slot(tmp_path: Path) -> None:
    """The first wingman 4 m behind and 6 m right of its slot all the way (formed: 7.2 m):
    its RMS error after forming is (4, 6, 0) forward / left / up, the others' none."""
    path = ROOT / "examples" / "paper_table3.json"
    mission = load_mission_file(path)
    t = np.arange(0.0, 40.0, 0.1)
    tracks = _flown(mission, t, np.full_like(t, -6.0))
    first = mission.wingmen[0].id
    tracks[first][:, 1] -= 4.0
    _write_observer(tmp_path, mission, t, tracks)
    rec = {"mission": mission.name, "mission_file": str(path), "condition": "f",
           "dir": str(tmp_path), "window_s": [5.0, 70.0]}  # fmt: skip
    cells = {
        int(line.split()[2]): line.split()[-5:] for line in axes_report([rec]).splitlines()[1:]
    }
    assert [float(x) for x in cells[first][::2]] == pytest.approx([4.0, 6.0, 0.0], abs=0.2)
    for w in mission.wingmen[1:]:
        assert [float(x) for x in cells[w.id][::2]] == pytest.approx([0.0, 0.0, 0.0], abs=0.2)


def test_the_slot_error_is_split_into_the_straight_legs_and_the_turns(tmp_path: Path) -> None:
    """The leader climbs east at 3° for 20 s, flies level, turns left 90° at 4.5°/s, and
    flies north; the first wingman is 6 m off its slot in the climb, 3 m on the level
    straight legs and 12 m in the turn: RMS 4.2 m straight, 3 m level, 12 m in the turn."""
    path = ROOT / "examples" / "paper_table3.json"
    mission = load_mission_file(path)
    t = np.arange(0.0, 80.0, 0.1)
    rate = np.where((t >= 30.0) & (t < 50.0), np.radians(4.5), 0.0)
    gamma = np.where(t < 20.0, np.radians(3.0), 0.0)
    course = np.cumsum(rate) * 0.1
    x, y = np.cumsum(100.0 * np.cos(course)) * 0.1, np.cumsum(100.0 * np.sin(course)) * 0.1
    z = 300.0 + np.cumsum(100.0 * np.tan(gamma)) * 0.1
    tracks = {mission.leader.id: np.column_stack([t, x, y, z, t * 0 + 300])}
    off = np.where(rate > 0.0, 12.0, np.where(t < 20.0, 6.0, 3.0))
    for k, w in enumerate(mission.wingmen):
        assert w.slot is not None
        sx, sy, _ = w.slot
        wx = x + sx * np.cos(gamma) * np.cos(course) - sy * np.sin(course)
        wy = y + sx * np.cos(gamma) * np.sin(course) + sy * np.cos(course)
        wz = z + sx * np.sin(gamma)  # the slot behind is lower in the climbing frame
        if k == 0:
            wx, wy = wx - off * np.sin(course), wy + off * np.cos(course)  # to its left
        tracks[w.id] = np.column_stack([t, wx, wy, wz, t * 0 + 300])
    _write_observer(tmp_path, mission, t, tracks)
    rec = {"mission": mission.name, "mission_file": str(path), "condition": "a",
           "dir": str(tmp_path), "window_s": [0.0, 70.0 + 30.0]}  # fmt: skip
    split = run_turns(rec)
    assert split is not None
    assert split.straight_m == pytest.approx(np.sqrt((20 * 36 + 40 * 9) / 60), abs=0.5)
    assert split.level_m == pytest.approx(3.0, abs=0.5)
    assert split.turns_m == pytest.approx(12.0, abs=1.0)
    row = turns_report([rec]).splitlines()[1].split()
    assert row[:3] == [mission.name, "a", "1"]


def test_a_formation_takeoffs_straight_legs_are_also_measured_once_airborne(
    tmp_path: Path,
) -> None:
    """Formed on the runway, the wingmen climb beside a leader climbing at 20° in TAKEOFF
    for 9 s (in its climbing frame a slot 200 m behind lies 68 m lower), then fly 2 m off
    their slots, and turn: the straight legs count the takeoff; after it, 2 m."""
    path = ROOT / "examples" / "paper_table3.json"
    mission = load_mission_file(path)
    t = np.arange(0.0, 80.0, 0.1)
    rate = np.where((t >= 40.0) & (t < 50.0), np.radians(4.5), 0.0)
    gamma = np.where((t >= 1.0) & (t < 10.0), np.radians(20.0), 0.0)
    course = np.cumsum(rate) * 0.1
    x, y = np.cumsum(30.0 * np.cos(course)) * 0.1, np.cumsum(30.0 * np.sin(course)) * 0.1
    z = np.cumsum(30.0 * np.tan(gamma)) * 0.1
    tracks = {mission.leader.id: np.column_stack([t, x, y, z, z])}
    for w in mission.wingmen:
        assert w.slot is not None
        sx, sy, _ = w.slot
        beside = np.where(t < 10.0, 0.0, 2.0)  # 2 m to the left once airborne
        wx = x + sx * np.cos(course) - (sy + beside) * np.sin(course)
        wy = y + sx * np.sin(course) + (sy + beside) * np.cos(course)
        tracks[w.id] = np.column_stack([t, wx, wy, z, z])  # level with the leader
    _write_observer(tmp_path, mission, t, tracks, modes=[[0, 13], [10000, 15]])
    rec = {"mission": mission.name, "mission_file": str(path), "condition": "a",
           "dir": str(tmp_path), "window_s": [0.0, 80.0 + 30.0]}  # fmt: skip
    assert takeoff_ended_s(tmp_path / "observer.json") == pytest.approx(10.0)
    split = run_turns(rec)
    assert split is not None
    assert split.straight_m > 10.0
    assert split.airborne_m == pytest.approx(2.0, abs=0.3)
    _write_observer(tmp_path, mission, t, tracks)  # no TAKEOFF flown
    assert takeoff_ended_s(tmp_path / "observer.json") is None
    split = run_turns(rec)
    assert split is not None
    assert split.airborne_m is None
