"""The campaign's command line: mission names resolve to the repository's examples and files
to absolute paths (its processes run in the repository, not where it was started)."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

from gcs_ppf.tools.campaign import ROOT, mission_path


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
