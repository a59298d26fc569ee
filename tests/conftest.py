"""Shared fixtures: the paper's missions and their plans (planned once per session)."""

from __future__ import annotations

import os
from pathlib import Path

import pytest
from hypothesis import HealthCheck, settings

from gcs_ppf.mission import Mission, load_mission_file
from gcs_ppf.offline.plan import PlanRun, plan_mission

ROOT = Path(__file__).resolve().parent.parent
EXAMPLES = ROOT / "examples"

settings.register_profile(
    "ci", max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow]
)
settings.register_profile("dev", max_examples=15, deadline=None)
settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "ci"))


@pytest.fixture(scope="session")
def table2() -> Mission:
    return load_mission_file(EXAMPLES / "paper_table2.json")


@pytest.fixture(scope="session")
def table3() -> Mission:
    return load_mission_file(EXAMPLES / "paper_table3.json")


@pytest.fixture(scope="session")
def table2_ppf(table2: Mission) -> PlanRun:
    return plan_mission(table2, method="ppf")


@pytest.fixture(scope="session")
def table2_apf(table2: Mission) -> PlanRun:
    return plan_mission(table2, method="apf")


@pytest.fixture(scope="session")
def table3_ppf(table3: Mission) -> PlanRun:
    return plan_mission(table3, method="ppf")


@pytest.fixture(scope="session")
def table3_apf(table3: Mission) -> PlanRun:
    return plan_mission(table3, method="apf")
