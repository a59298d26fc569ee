"""Random scenes for the property tests: the package's scene families, drawn by hypothesis.

The families and their generator are ``gcs_ppf.offline.sweep`` (``families.py``,
``scenes.py``); here hypothesis supplies the numbers, so a failing scene shrinks to a
simple one. *Feasible* (``FEASIBLE``) means the guarantees behind the influence radius
(CONVENTIONS §2 erratum 4) and the teammate rules can hold:

* the influence spheres of the obstacles at v_max (keep-out plus a turn radius) do not
  overlap, so a vehicle answers to one obstacle at a time;
* every start and the target lie outside every influence sphere at v_max;
* vehicles start at least 300 m apart and their slots are at least the safe distance
  apart (the mission validator's rule);
* obstacles do not move (moving obstacles are tested head-on in tests/scenarios);
* with ``ground``, the ground lies below every start and the target by more than the
  safe distance plus a pull-up from the start pitch (obstacles may reach into it).
"""

from __future__ import annotations

from hypothesis import assume
from hypothesis import strategies as st

from gcs_ppf.mission import Mission
from gcs_ppf.offline.sweep.families import FEASIBLE
from gcs_ppf.offline.sweep.scenes import mission_document
from gcs_ppf.offline.sweep.spec import GroundSpec, SceneSpec


class HypothesisDraws:
    """``gcs_ppf.offline.sweep.scenes.Draws`` from hypothesis: ``require`` is ``assume``."""

    def __init__(self, draw: st.DrawFn) -> None:
        self._draw = draw

    def uniform(self, low: float, high: float) -> float:
        return self._draw(st.floats(low, high))

    def integer(self, low: int, high: int) -> int:
        return self._draw(st.integers(low, high))

    def require(self, condition: bool) -> None:
        assume(condition)


@st.composite
def missions(draw: st.DrawFn, spec: SceneSpec) -> Mission:
    """Scenes of the family ``spec``."""
    return Mission.model_validate(mission_document(spec, HypothesisDraws(draw)))


def feasible_missions(
    max_wingmen: int = 4, max_obstacles: int = 4, ground: bool = False
) -> st.SearchStrategy[Mission]:
    """Feasible scenes of up to ``max_wingmen`` wingmen and ``max_obstacles`` obstacles, over
    a ground when ``ground``."""
    spec = FEASIBLE.model_copy(
        update={
            "fleet": FEASIBLE.fleet.model_copy(update={"wingmen": (0, max_wingmen)}),
            "obstacles": FEASIBLE.obstacles.model_copy(update={"count": (0, max_obstacles)}),
            "ground": GroundSpec() if ground else None,
        }
    )
    return missions(SceneSpec.model_validate(spec.model_dump()))
