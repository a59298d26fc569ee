"""GCS-side MAVLink edges: ArduPlane facts, codec, command builders, telemetry decoding."""
