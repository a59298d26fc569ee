"""One vehicle on two links, or two vehicles with one id; and the link that commands it."""

from __future__ import annotations

import pytest

from gcs_ppf.service.link_choice import (
    DWELL_S,
    Fix,
    LinkSeen,
    apart_m,
    better_link,
    same_vehicle,
)

DEG_PER_M = 1.0 / 111_195.0


def carried(fixes: list[tuple[int, float]]) -> LinkSeen:
    """A link that carried positions (boot ms, metres north of 47°)."""
    seen = LinkSeen()
    for boot, north in fixes:
        seen.fixes.append(Fix(boot, 47.0 + north * DEG_PER_M, 8.0))
    return seen


def track(first_ms: int, last_ms: int, speed_m_s: float = 100.0) -> list[tuple[int, float]]:
    """A vehicle flying north at ``speed_m_s``, its positions every 100 ms."""
    return [(t, speed_m_s * t / 1000.0) for t in range(first_ms, last_ms + 1, 100)]


def test_one_vehicle_reports_one_place_at_one_time_however_late_a_link_brings_it() -> None:
    fast = carried(track(0, 20_000))
    slow = carried(track(0, 17_600))  # 2.4 s behind: a radio carrying more than it can
    assert same_vehicle([fast, slow]) is True
    other = carried([(t, north + 300.0) for t, north in track(0, 20_000)])  # 300 m apart
    assert same_vehicle([fast, other]) is False
    assert same_vehicle([fast, LinkSeen()]) is None  # not known yet
    far_behind = carried(track(0, 2_000))  # its last position older than the other keeps
    assert same_vehicle([carried(track(40_000, 60_000)), far_behind]) is None
    assert apart_m(Fix(0, 47.0, 8.0), Fix(0, 47.0, 8.001)) == pytest.approx(75.85, abs=0.1)


def test_the_commanding_link_stays_while_it_keeps_up() -> None:
    links = {1: carried(track(0, 10_000)), 2: carried(track(0, 10_400))}
    assert better_link(1, links, (1, 2), 1.0, 60.0) == (1, None)  # 0.4 s behind: not yet


def test_a_link_falling_behind_or_silent_gives_way() -> None:
    links = {1: carried(track(0, 10_000)), 2: carried(track(0, 10_600))}
    assert better_link(1, links, (1, 2), 1.0, 60.0) == (2, "behind")
    assert better_link(1, links, (1, 2), 10.0, 60.0) == (1, None)  # ×10: 2.5 s of its clock
    links[2] = carried(track(0, 12_600))
    assert better_link(1, links, (1, 2), 10.0, 60.0) == (2, "behind")
    assert better_link(1, links, (2,), 1.0, 60.0) == (2, "gone")  # link 1 timed out


def test_a_link_given_the_commands_keeps_them_a_while() -> None:
    """No flapping between two links read one burst at a time."""
    links = {1: carried(track(0, 10_000)), 2: carried(track(0, 10_600))}
    assert better_link(1, links, (1, 2), 1.0, DWELL_S - 0.1) == (1, None)
    assert better_link(1, links, (1, 2), 1.0, DWELL_S) == (2, "behind")
    assert better_link(1, links, (2,), 1.0, 0.0) == (2, "gone")  # gone: at once
