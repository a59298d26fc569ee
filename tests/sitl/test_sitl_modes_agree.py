"""The SITL's ArduPlane modes and the service's decoder use the same numbers."""

from __future__ import annotations

from gcs_ppf.mavlink.ardupilot import PlaneMode as ServicePlaneMode
from sitl.modes import PlaneMode as SitlPlaneMode


def test_every_mode_the_sitl_flies_has_the_number_the_service_decodes() -> None:
    for mode in SitlPlaneMode:
        assert ServicePlaneMode[mode.name].value == mode.value
