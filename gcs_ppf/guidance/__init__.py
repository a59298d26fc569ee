"""Closed-loop guidance, pure: telemetry and airframes in, what to command out; no I/O."""
