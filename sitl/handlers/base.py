"""What every inbound-message handler of the SITL shares: its signature and the finite check.

A handler takes the autopilot, the decoded message, the sender (sysid, compid), the
vehicle's kinematics and the clocks, and fills an Outbox.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

from sitl.autopilot import Autopilot, Clock, Kinematics, Outbox

Src = tuple[int, int]
Handler = Callable[[Autopilot, Any, Src, Kinematics, Clock, Outbox], None]


def finite(*values: float) -> bool:
    """True if every value is a finite number (MAVLink floats may be NaN or infinite)."""
    return all(math.isfinite(v) for v in values)
