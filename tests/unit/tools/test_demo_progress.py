"""make run's progress lines show the formation the service watches."""

from __future__ import annotations

from gcs_ppf.tools.demo import formation_line, formation_summary


def test_the_progress_line_names_the_worst_wingman_and_the_hold() -> None:
    status = {"formed": False, "worst_wingman_id": 3, "worst_error_m": 412.3, "current_hold_s": 0.0}
    line = formation_line(status)
    assert "not formed" in line
    assert "412.3 m" in line
    assert "wingman 3" in line
    assert formation_line({"formed": True, "worst_wingman_id": 2, "worst_error_m": 4.0,
                           "current_hold_s": 12.5}).startswith("formation formed")  # fmt: skip
    assert formation_line(None) == "formation -"


def test_the_summary_gives_the_runs_figures_or_says_it_never_formed() -> None:
    assert formation_summary({"time_to_form_s": None}) == "formation: never formed"
    summary = formation_summary({"time_to_form_s": 26.0, "fraction_in_formation": 0.9,
                                 "longest_hold_s": 20.0, "rms_slot_error_m": 3.1,
                                 "p95_slot_error_m": 8.0})  # fmt: skip
    assert "formed after 26.0 s" in summary
    assert "90 %" in summary
