"""MAVProxy, the ground station many ArduPilot users keep open, beside the service: run
non-interactive on a ``tcpin`` forward while Table 3 flies with its zones up as every
vehicle's own fence, it detects all five vehicles, follows their modes and reports no fence
breach (ArduPlane's SYS_STATUS geofence bits as the SITL sets them).

``MAVPROXY=…/mavproxy.py .venv/bin/pytest -m mavproxy -s tests``; skipped otherwise.
``make mavproxy-check`` installs MAVProxy from PyPI into a venv of its own (it pulls OpenCV
and wxPython's kin, too heavy for the project's) and runs it.
"""

from __future__ import annotations

import json
import os
import re
from contextlib import ExitStack
from pathlib import Path

import pytest

from gcs_ppf.tools.campaign import process
from gcs_ppf.tools.demo import http_json as http
from gcs_ppf.tools.observer import free_port
from tests.conftest import EXAMPLES
from tests.integration.test_service_sitl import check_safety, fly

MAVPROXY = os.environ.get("MAVPROXY", "")
MISSION = EXAMPLES / "paper_table3_fenced.json"  # an inclusion polygon and a cylinder
MAVPROXY_SYSID = 250  # neither a vehicle's id nor the service's 255

pytestmark = [
    pytest.mark.mavproxy,
    pytest.mark.integration,
    pytest.mark.skipif(
        not (MAVPROXY and Path(MAVPROXY).is_file()),
        reason=f"MAVPROXY={MAVPROXY!r} does not name mavproxy.py (make mavproxy-check)",
    ),
]


def test_mavproxy_on_a_forward_sees_every_vehicle_and_no_fence_breach(tmp_path: Path) -> None:
    port = free_port()
    log = tmp_path / "mavproxy.log"
    mavproxy = [
        MAVPROXY,
        f"--master=tcp:127.0.0.1:{port}",
        "--non-interactive",
        f"--source-system={MAVPROXY_SYSID}",
        f"--state-basedir={tmp_path}",
    ]
    with ExitStack() as stack:

        def during(api: str, mid: int) -> None:
            # MAVProxy joins once the run flies, as an operator's would, to its end
            stack.enter_context(process(mavproxy, log, {"HOME": str(tmp_path)}))

        def after(api: str, mid: int) -> None:
            _, body = http("GET", f"{api}/missions/{mid}/events")
            fenced.extend(e["vehicle_id"] for e in body if e["kind"] == "fence_set")

        fenced: list[int] = []
        flight = fly(
            tmp_path,
            json.loads(MISSION.read_text()),
            env_extra={"GCS_PPF_FORWARD": json.dumps([f"tcpin:127.0.0.1:{port}"])},
            during=during,
            after=after,
        )
    said = log.read_text(errors="replace")
    detected = sorted({int(v) for v in re.findall(r"Detected vehicle (\d+):1", said)})
    fence_lines = [line for line in said.splitlines() if re.search("fence", line, re.IGNORECASE)]
    print(f"\nMAVProxy: detected {detected}; its lines about a fence: {fence_lines[:5]}")
    assert sorted(fenced) == [1, 2, 3, 4, 5]  # every vehicle's fence up and enabled
    assert detected == [1, 2, 3, 4, 5], said[-2000:]
    assert not [line for line in fence_lines if re.search("breach", line, re.IGNORECASE)]
    assert "GUIDED" in said  # the vehicles' modes, as MAVProxy follows them
    assert flight.final["state"] == "completed", flight.final
    check_safety(flight)
