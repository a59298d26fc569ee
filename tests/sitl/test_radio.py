"""The SITL's telemetry radio (``sitl.radio``): what a 57,600-baud link carries in a
simulated second, the burst its buffer takes, and what is dropped."""

from __future__ import annotations

import pytest

from sitl.radio import BUFFER_S, RadioBudget
from sitl.server import parse_serial


def test_a_57600_baud_radio_carries_5760_bytes_a_second_and_drops_the_rest() -> None:
    radio = RadioBudget(57600)
    sent = sum(radio.admit(40, k * 0.001) for k in range(10_000))  # 40 kB/s offered, 10 s
    assert radio.passed_bytes == 40 * sent
    carried = radio.passed_bytes / 10.0
    assert carried == pytest.approx(5760.0, rel=0.05)
    assert radio.dropped_bytes == 40 * 10_000 - radio.passed_bytes


def test_a_burst_within_the_buffer_passes_whole_and_drains() -> None:
    radio = RadioBudget(57600)
    burst = int(BUFFER_S * 5760) // 40
    assert all(radio.admit(40, 0.0) for _ in range(burst))
    assert not radio.admit(40, 0.0)
    assert radio.admit(40, 0.1)  # 576 bytes drained in 0.1 s
    assert radio.dropped_bytes == 40


def test_what_fits_is_never_dropped() -> None:
    radio = RadioBudget(57600)
    assert all(radio.admit(40, k * 0.01) for k in range(1000))  # 4000 B/s, 10 s
    assert radio.dropped_bytes == 0


@pytest.mark.parametrize(
    ("text", "expected"),
    [
        ("/dev/pts/3", ("/dev/pts/3", 57600)),
        ("/tmp/a:115200", ("/tmp/a", 115200)),
        ("/tmp/a,9600", ("/tmp/a", 9600)),
    ],
)
def test_serial_devices_and_their_baud(text: str, expected: tuple[str, int]) -> None:
    assert parse_serial(text) == expected


@pytest.mark.parametrize("text", ["", ":57600", "/tmp/a:fast", "/tmp/a:0"])
def test_a_bad_serial_device_is_named(text: str) -> None:
    with pytest.raises(ValueError, match="--serial"):
        parse_serial(text)
