"""The campaign's command line: mission names resolve to the repository's examples and files
to absolute paths (its processes run in the repository, not where it was started); and the
formation as its observer's tracks show it."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest

from gcs_ppf.mission import load_mission_file
from gcs_ppf.tools.campaign import ROOT, formation_seen, mission_path


def test_a_mission_name_is_one_of_the_repository_examples() -> None:
    assert (ROOT / "pyproject.toml").is_file()
    assert mission_path("paper_table3") == ROOT / "examples" / "paper_table3.json"
    assert mission_path("paper_table3").is_file()


def test_a_relative_mission_file_is_made_absolute(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    (tmp_path / "m.json").write_text("{}")
    monkeypatch.chdir(tmp_path)
    p = mission_path("m.json")
    assert p.is_absolute()
    assert p == tmp_path / "m.json"
    assert os.path.samefile(p, tmp_path / "m.json")


def test_help_lists_the_conditions(capsys: pytest.CaptureFixture[str]) -> None:
    """A condition's label holds a per cent sign, which argparse expands in help texts."""
    from gcs_ppf.tools.campaign import main

    with pytest.raises(SystemExit) as exited:
        main(["--help"])
    assert exited.value.code == 0
    assert "20 % loss" in capsys.readouterr().out


def _line_east(t: np.ndarray, offset: tuple[float, float, float]) -> np.ndarray:
    """A track [t, x, y, z, height] flying east at 100 m/s at 300 m, shifted by ``offset``."""
    x, y, z = 100.0 * t + offset[0], np.full_like(t, offset[1]), np.full_like(t, 300.0 + offset[2])
    return np.column_stack([t, x, y, z, z])


def test_the_formation_seen_is_the_worst_wingmans_distance_from_its_slot() -> None:
    """Table 3's wingmen flown exactly on their slots (Eq. 6: x forward, y left) behind a
    leader flying east: 0 m, held the whole window; one of them 30 m off its slot for the
    first half: 30 m until then, so the best moment is 0 m, held the second half; off all
    along: 30 m, never held.  A lone leader, or a wingman never heard: None."""
    mission = load_mission_file(ROOT / "examples" / "paper_table3.json")
    t = np.arange(0.0, 40.0, 0.05)
    leader = _line_east(t, (0.0, 0.0, 0.0))
    on_slots = {mission.leader.id: leader}
    for w in mission.wingmen:
        assert w.slot is not None
        on_slots[w.id] = _line_east(t, (w.slot[0], w.slot[1], w.slot[2]))
    formation, held = formation_seen(mission, on_slots, 5.0, 35.0)
    assert formation is not None
    assert formation < 1.0
    assert held is not None
    assert held >= 29.5
    late = dict(on_slots)
    w = mission.wingmen[0]
    assert w.slot is not None
    shifted = _line_east(t, (w.slot[0], w.slot[1] + 30.0, w.slot[2]))
    late[w.id] = np.where((t < 20.0)[:, None], shifted, on_slots[w.id])
    formation, held = formation_seen(mission, late, 5.0, 35.0)
    assert formation is not None
    assert formation < 1.0
    assert held is not None
    assert 14.0 <= held <= 15.5
    off = dict(on_slots)
    off[w.id] = shifted
    formation, held = formation_seen(mission, off, 5.0, 35.0)
    assert formation is not None
    assert abs(formation - 30.0) < 1.0
    assert held == 0.0
    silent = dict(on_slots)
    silent[w.id] = np.zeros((0, 5))
    assert formation_seen(mission, silent, 5.0, 35.0) == (None, None)
