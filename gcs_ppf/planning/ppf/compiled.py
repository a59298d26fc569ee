"""How the hot loops are compiled: numba without its reference counting.

numba counts references to every array a compiled function binds: passing an array on,
slicing a row of it or re-binding it in an inlined equation group costs an atomic
increment and decrement (``NRT_incref``/``NRT_decref``).  In the PPF step these took 40 %
of a five-vehicle step (perf, issue 12); numba's pruning of the pairs removes them only
within simple blocks, not in the loops over vehicles and teammates.  A function that
allocates nothing and keeps no array beyond its call needs none of them: every array it
sees is held by its caller for the whole call.  numba compiles such a function without
its runtime when asked (its private option ``_nrt=False``); it then refuses to compile an
allocation ("NRT required but not enabled"), so a mistake is a compile error, not a leak.
The arithmetic is the same code: the plans are bit-identical.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, TypeVar, cast

from numba import njit

F = TypeVar("F", bound=Callable[..., Any])

_njit: Any = njit  # numba's type stubs leave out its private options


def njit_without_refcounts(function: F) -> F:
    """``njit(cache=True)`` without numba's reference counting (see the module)."""
    return cast(F, _njit(cache=True, _nrt=False)(function))
