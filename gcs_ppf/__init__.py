"""gcs-ppf: piecewise-potential-field formation planning for fixed-wing UAVs."""

import hashlib
import os
from pathlib import Path

# numba caches each compiled function by the timestamp of its own file only, so a kernel
# that calls into another module would keep a stale compilation after that module
# changes.  Key the cache directory by the kernels' sources instead (before numba loads).
_KERNEL_SOURCES = (
    "planning/ppf/primitives.py",
    "planning/ppf/kernel.py",
    "planning/ppf/neighbours.py",
    "planning/apf.py",
    "planning/rollout.py",
)
if "NUMBA_CACHE_DIR" not in os.environ:
    _here = Path(__file__).parent
    _digest = hashlib.sha256(b"".join((_here / f).read_bytes() for f in _KERNEL_SOURCES))
    os.environ["NUMBA_CACHE_DIR"] = str(
        Path.home() / ".cache" / "gcs-ppf" / f"numba-{_digest.hexdigest()[:16]}"
    )
