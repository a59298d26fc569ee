"""The service's compiled kernels: the online planner's and the run-time assurance's.

``python -m gcs_ppf.service.kernels`` builds them into numba's cache (``make install`` does,
so that no first run waits for them: compiled in flight, a run waited 54 s before it
launched, campaign, session 5); the service loads them in a thread when it starts
(``FormationService.running``).
"""

from __future__ import annotations

import functools
import gc
import sys
import time

from gcs_ppf.guidance import assurance
from gcs_ppf.guidance.online import warm_up
from gcs_ppf.service.settings import Settings


def load_kernels(planner_dt_s: float) -> None:
    """The planner's and the assurance's compiled kernels loaded (numba's cache, or
    compiled), then, once per process, everything loaded so far left out of the garbage
    collector's full passes (``gc.freeze``): in flight at ×10 a full pass over the
    libraries and kernels held the event loop up to 290 ms (4 campaign runs); since, at
    most 126 ms (2 runs)."""
    warm_up(planner_dt_s)
    assurance.warm_up()
    _freeze_once()


@functools.cache
def _freeze_once() -> None:
    gc.collect()
    gc.freeze()


def main() -> int:
    started = time.perf_counter()
    # The settings' default Δt: the kernels compiled do not depend on it.
    load_kernels(Settings.model_fields["planner_dt_s"].default)
    print(f"compiled kernels ready in numba's cache ({time.perf_counter() - started:.1f} s)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
