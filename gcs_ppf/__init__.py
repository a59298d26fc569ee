"""gcs-ppf: piecewise-potential-field formation planning for fixed-wing UAVs."""

import hashlib
import os
from pathlib import Path

# numba caches each compiled function by the timestamp of its own file only, so a kernel
# that calls into another module would keep a stale compilation after that module
# changes.  Key the cache directory by the kernels' sources instead (before numba loads).
_KERNEL_SOURCES = ("planning/ppf/*.py", "planning/apf.py", "planning/rollout.py")
if "NUMBA_CACHE_DIR" not in os.environ:
    _here = Path(__file__).parent
    _files = sorted(f for pattern in _KERNEL_SOURCES for f in _here.glob(pattern))
    _digest = hashlib.sha256(b"".join(f.read_bytes() for f in _files))
    os.environ["NUMBA_CACHE_DIR"] = str(
        Path.home() / ".cache" / "gcs-ppf" / f"numba-{_digest.hexdigest()[:16]}"
    )
