"""A scene family: the ranges a sweep draws its random scenes from (a spec file, validated).

A family says how many wingmen and obstacles a scene has, where the vehicles start and the
target lies, how big the obstacles are and how fast they move, the vehicles' initial
state, the envelope (``limits``, the mission's model) and the planner settings (``planner``,
the mission's model: method, Δt, max_time). Every key has a default, and the defaults are
the *feasible* family of the property tests (docs/sweeps.md), so a spec file states only
what it changes::

    name = "big-v"
    planner = { dt = 0.02, max_time = 120.0 }

    [fleet]
    wingmen = [6, 12]             # inclusive range of counts
    slot_spacing_m = [80.0, 200.0]

    [obstacles]
    count = [2, 6]
    radius_m = [100.0, 400.0]
    speed_m_s = [0.0, 50.0]       # horizontal, in a random heading

Spec files are TOML or JSON. Unknown keys and bad values are errors that name the field
(``obstacles.radius_m: low 700 exceeds high 30``), as for missions.
"""

from __future__ import annotations

import json
import math
import tomllib
from pathlib import Path
from typing import Annotated, Literal, TypeVar

from pydantic import AfterValidator, BaseModel, ConfigDict, Field, ValidationError, model_validator

from gcs_ppf.mission import Limits, PlannerSettings, describe_validation_error

Number = TypeVar("Number", int, float)


def _ordered(pair: tuple[Number, Number]) -> tuple[Number, Number]:
    low, high = pair
    if low > high:
        raise ValueError(f"low {low:g} exceeds high {high:g}")
    return pair


FloatRange = Annotated[tuple[float, float], AfterValidator(_ordered)]
"""[low, high], both included (a single value: low = high)."""
CountRange = Annotated[
    tuple[Annotated[int, Field(ge=0)], Annotated[int, Field(ge=0)]], AfterValidator(_ordered)
]
NonNegative = Annotated[float, Field(ge=0.0)]
MAX_WINGMEN = 253
"""Vehicle ids are 1 … 254 (MAVLink system ids), the leader's is 1."""


class _Strict(BaseModel):
    """Unknown keys and non-finite numbers are errors; specs are values."""

    model_config = ConfigDict(extra="forbid", allow_inf_nan=False, frozen=True)


class Box(_Strict):
    """An axis-aligned box of the ICS, positions drawn uniformly in it: each coordinate is
    ``center_m`` plus a draw in ± ``half_size_m`` (metres)."""

    center_m: tuple[float, float, float]
    half_size_m: tuple[NonNegative, NonNegative, NonNegative]


class FleetSpec(_Strict):
    """The formation: its size, where it starts, its slots, its initial state."""

    wingmen: CountRange = (0, 4)
    start_box: Box = Box(center_m=(-6000.0, 0.0, 0.0), half_size_m=(3000.0, 3000.0, 500.0))
    start_gap_m: float = Field(default=300.0, gt=0.0)
    """Vehicles start at least this far apart (scenes drawn closer are drawn again)."""
    slot_spacing_m: FloatRange = (60.0, 400.0)
    """Slots form a V behind the leader, in rows of two: row k (1, 2, …) lies k × spacing
    behind and k × spacing to the left or right of it."""
    pitch_rad: FloatRange = (-0.3, 0.3)
    yaw_rad: FloatRange = (-math.pi, math.pi)
    speed_m_s: FloatRange | None = None
    """Initial speeds; None: ``limits.v_min`` … ``limits.v_max``."""


class ObstacleSpec(_Strict):
    """Spherical obstacles: how many are tried, where, how big, how fast.

    ``placement = "apart"`` keeps the influence spheres at v_max (keep-out plus a turn
    radius, CONVENTIONS §2 erratum 4) of any two obstacles from overlapping, so a vehicle
    answers to one obstacle at a time; ``"overlapping"`` lets them overlap (the *dense*
    family). Either way an obstacle whose influence sphere would hold a start or the
    target is left out, so a scene may have fewer obstacles than drawn.
    """

    count: CountRange = (0, 4)
    placement: Literal["apart", "overlapping"] = "apart"
    box: Box = Box(center_m=(0.0, 0.0, 0.0), half_size_m=(4000.0, 3000.0, 500.0))
    radius_m: FloatRange = (30.0, 700.0)
    speed_m_s: FloatRange = (0.0, 0.0)
    """Each obstacle moves horizontally at a speed drawn here, in a random heading."""


class ZoneSpec(_Strict):
    """The obstacles drawn, each turned into a zone inside its sphere with the sphere's
    height band: ``"mixed"``, a vertical cylinder or an extruded polygon of 3–8 corners
    (star-shaped, so convex or not), half and half; ``"pocket"``, a U whose opening (60 %
    of its width) faces the leader's start, a concave pocket the way in.  Every start and
    the target lie outside each zone's influence at v_max measured from its surface, and
    the zones' influence regions apart (a scene drawn otherwise is drawn again)."""

    shape: Literal["mixed", "pocket"] = "mixed"


class GroundSpec(_Strict):
    """Flat ground under the scene (the mission's ``ground``): it lies below the lowest start
    and the target by the safe distance, a full-rate pull-up from the steepest start pitch
    (``pull_up_margin_m``), and a depth drawn from ``depth_m``."""

    depth_m: FloatRange = (0.0, 400.0)


class SceneSpec(_Strict):
    """A family of random scenes (see the module's docstring); the defaults are *feasible*."""

    name: str = Field(default="feasible", min_length=1, max_length=100)
    target_box: Box = Box(center_m=(6000.0, 0.0, 0.0), half_size_m=(3000.0, 3000.0, 500.0))
    fleet: FleetSpec = FleetSpec()
    obstacles: ObstacleSpec = ObstacleSpec()
    ground: GroundSpec | None = None
    zones: ZoneSpec | None = None
    """None: the obstacles stay spheres."""
    limits: Limits = Limits()
    planner: PlannerSettings = PlannerSettings(max_time=90.0)
    obstacle_passage: Literal["each", "formation"] = "each"
    """The missions' ``obstacle_passage``: each vehicle round the obstacles, or the whole
    formation (``gcs_ppf.mission.Mission.obstacle_passage``)."""

    @model_validator(mode="after")
    def _consistent(self) -> SceneSpec:
        for problem in spec_problems(self):
            raise ValueError(problem)
        return self

    @property
    def initial_speed_m_s(self) -> tuple[float, float]:
        """The range initial speeds are drawn from."""
        return self.fleet.speed_m_s or (self.limits.v_min, self.limits.v_max)


def spec_problems(spec: SceneSpec) -> list[str]:
    """Cross-field checks that keep every drawn scene a valid mission; each problem starts
    with the field it names."""
    lim, fleet = spec.limits, spec.fleet
    problems = []
    if fleet.wingmen[1] > MAX_WINGMEN:
        problems.append(f"fleet.wingmen: at most {MAX_WINGMEN} (vehicle ids 1 … 254)")
    if fleet.start_gap_m < lim.safe_distance_uav:
        problems.append("fleet.start_gap_m: must be at least limits.safe_distance_uav")
    closest_slots = fleet.slot_spacing_m[0] * math.sqrt(2.0)  # the leader and row 1
    if closest_slots < lim.safe_distance_uav:
        problems.append(
            f"fleet.slot_spacing_m: slots {closest_slots:g} m apart at the low end, closer "
            f"than limits.safe_distance_uav (spacing ≥ safe distance / √2 is needed)"
        )
    if not -math.pi / 2 <= fleet.pitch_rad[0] <= fleet.pitch_rad[1] <= math.pi / 2:
        problems.append("fleet.pitch_rad: must lie in [-π/2, π/2]")
    if not -math.pi <= fleet.yaw_rad[0] <= fleet.yaw_rad[1] <= math.pi:
        problems.append("fleet.yaw_rad: must lie in [-π, π]")
    low, high = spec.initial_speed_m_s
    if not lim.v_min <= low <= high <= lim.v_max:
        problems.append("fleet.speed_m_s: must lie in [limits.v_min, limits.v_max]")
    if spec.obstacles.radius_m[0] <= 0.0:
        problems.append("obstacles.radius_m: must be positive")
    if spec.obstacles.speed_m_s[0] < 0.0:
        problems.append("obstacles.speed_m_s: must not be negative")
    if spec.zones is not None and spec.obstacles.speed_m_s[1] > 0.0:
        problems.append("zones: zones do not move (obstacles.speed_m_s must be 0)")
    return problems


def pull_up_margin_m(spec: SceneSpec) -> float:
    """Height a start needs above the ground's keep-out: levelling out from the steepest
    start pitch at v_max on a pull-up arc of radius v_max/ω loses ρ(1 − cos θ) (Table 1:
    573 · (1 − cos 0.3) = 26 m), plus three steps of travel; at least 40 m, the margin the
    property tests were written with."""
    lim = spec.limits
    rho = lim.v_max / min(lim.max_pitch_rate, lim.max_yaw_rate)
    steepest = max(abs(p) for p in spec.fleet.pitch_rad)
    return max(40.0, rho * (1.0 - math.cos(steepest)) + 3.0 * lim.v_max * spec.planner.dt)


class SpecError(ValueError):
    """A spec file that cannot be used; ``field`` names the offending field."""

    def __init__(self, field: str, message: str) -> None:
        super().__init__(f"{field}: {message}")
        self.field = field
        self.message = message


def parse_spec(raw: object, default_name: str = "feasible") -> SceneSpec:
    """Validate a decoded spec document (a TOML or JSON table); ``default_name`` when it
    has no ``name``. Raises ``SpecError`` naming the first bad field."""
    if not isinstance(raw, dict):
        raise SpecError("spec", "must be a table (TOML) or an object (JSON)")
    try:
        return SceneSpec.model_validate({"name": default_name, **raw})
    except ValidationError as exc:
        first = describe_validation_error(exc)[0]
        raise SpecError(first.field, first.message) from None


def load_spec_file(path: str | Path) -> SceneSpec:
    """Read a spec file (``.toml``, or JSON otherwise); its name defaults to the file's stem."""
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise SpecError("spec", f"cannot read {path}: {exc}") from None
    try:
        raw = tomllib.loads(text) if path.suffix == ".toml" else json.loads(text)
    except (tomllib.TOMLDecodeError, json.JSONDecodeError) as exc:
        kind = "TOML" if path.suffix == ".toml" else "JSON"
        raise SpecError("spec", f"not valid {kind}: {exc}") from None
    return parse_spec(raw, default_name=path.stem)
