"""gcs-ppf's built-in SITL: simulated fixed-wing vehicles that speak ArduPlane's MAVLink.

Run ``python -m sitl MISSION.json``; see sitl/README.md. This package never imports the
planner: it is a separate vehicle.
"""
