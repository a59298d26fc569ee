"""Processes around the service: the live demo, the tick-latency benchmark, real ArduPlane SITL."""
