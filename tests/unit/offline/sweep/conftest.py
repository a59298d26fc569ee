"""Rows for the sweep's tests: made up, with every kind of outcome and missing figure."""

from __future__ import annotations

from dataclasses import replace

import pytest

from gcs_ppf.offline.sweep.rows import Outcome, SceneRow

REACHED = SceneRow(
    family="feasible",
    index=0,
    seed=1,
    vehicles=3,
    obstacles=2,
    dt_s=0.01,
    outcome=Outcome.REACHED,
    reached=True,
    flight_time_s=60.0,
    straight_line_time_s=40.0,
    formation_time_s=20.5,
    min_separation_m=120.0,
    min_obstacle_clearance_m=300.0,
    min_ground_clearance_m=None,
    collisions=0,
    error="",
    planning_wall_time_s=0.02,
)


@pytest.fixture
def rows() -> list[SceneRow]:
    """Four feasible scenes (two reached, one not, one too close to an obstacle) and two of
    another family (a lone leader reached, an error)."""
    return [
        REACHED,
        replace(REACHED, index=1, flight_time_s=80.0, min_separation_m=60.0),
        replace(
            REACHED,
            index=2,
            outcome=Outcome.NOT_REACHED,
            reached=False,
            flight_time_s=None,
            formation_time_s=None,
        ),
        replace(REACHED, index=3, outcome=Outcome.CLEARANCE, min_obstacle_clearance_m=12.5),
        replace(
            REACHED,
            family="mine",
            vehicles=1,
            obstacles=0,
            min_separation_m=None,
            min_obstacle_clearance_m=None,
        ),
        replace(
            REACHED,
            family="mine",
            index=1,
            outcome=Outcome.ERROR,
            reached=False,
            vehicles=None,
            obstacles=None,
            flight_time_s=None,
            straight_line_time_s=None,
            formation_time_s=None,
            min_separation_m=None,
            min_obstacle_clearance_m=None,
            collisions=None,
            error='SceneError: mine: no valid scene, "quoted", with commas',
            planning_wall_time_s=None,
        ),
    ]
