"""Shared fixtures: the paper's missions and their plans (planned once per session)."""

from __future__ import annotations

import os
from pathlib import Path

import pytest
from hypothesis import HealthCheck, settings

from gcs_ppf.mission import Mission, load_mission_file
from gcs_ppf.offline.plan import PlanRun, plan_mission
from gcs_ppf.planning.ppf.primitives import KernelLimits

ROOT = Path(__file__).resolve().parent.parent
EXAMPLES = ROOT / "examples"
ARDUPLANE = KernelLimits(16.0, 28.0, 0.6, 0.8, 0.3, 0.3, 10.0, 50.0, 25.0, -float("inf"))
"""The ArduPlane-scale examples' limits as the kernel takes them."""

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
