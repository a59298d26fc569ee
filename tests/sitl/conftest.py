"""Every SITL test has a bounded run time: SIGALRM fails a test that runs over."""

from __future__ import annotations

import signal
from collections.abc import Iterator
from types import FrameType

import pytest

TEST_TIMEOUT_S = 90


def _expired(signum: int, frame: FrameType | None) -> None:
    raise TimeoutError(f"test ran over {TEST_TIMEOUT_S} s")


@pytest.fixture(autouse=True)
def _bounded_time() -> Iterator[None]:
    previous = signal.signal(signal.SIGALRM, _expired)
    signal.alarm(TEST_TIMEOUT_S)
    try:
        yield
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, previous)
