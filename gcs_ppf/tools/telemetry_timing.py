"""How far each vehicle's clock, as the service read it, strays from a steady one.

``python -m gcs_ppf.tools.telemetry_timing RUN_DIR`` reads the service's tlogs of a run
(``tlogs/link*.tlog``, each message stamped with our clock when the service read it) and
prints, per vehicle, how the ``time_boot_ms`` of its GLOBAL_POSITION_INT lagged a straight
line fitted to our reading times: in vehicle seconds, counted from the least late, and
what that is in altitude at the vehicle's median vertical speed.  Both a reading late
(the service busy) and a vehicle clock that paces unevenly (a SITL starved of CPU falls
behind and catches up) show here, and both are the same error to the service: it carries
each position on by the time since it was read at the clock's rate, so the vehicle is
not where the command is computed for; at the paper's scale (TECS's height gain 1.75 /s)
every metre of altitude that puts it off asks 1.75 m/s of climb or sink.
"""

from __future__ import annotations

import argparse
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray
from pymavlink import mavutil

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class ReadingLag:
    """One vehicle's readings: the fitted clock rate (vehicle s per s of ours) and the
    percentiles (50, 90, 99) of how far each lagged the fitted line, in vehicle seconds."""

    rate: float
    late_s: tuple[float, float, float]


def reading_lag(read_s: FloatArray, boot_s: FloatArray) -> ReadingLag:
    """How far messages stamped ``boot_s`` (vehicle time) read at ``read_s`` (ours) lag a
    steady clock: the residuals of a straight-line fit of the vehicle clock on ours,
    counted from the least late (a message is never read before it is sent)."""
    if len(read_s) < 3:
        raise ValueError(f"need at least 3 readings, got {len(read_s)}")
    rate, offset = np.polyfit(read_s, boot_s, 1)
    late = (rate * read_s + offset) - boot_s
    late = late - late.min()
    p50, p90, p99 = np.percentile(late, [50, 90, 99])
    return ReadingLag(float(rate), (float(p50), float(p90), float(p99)))


def positions_read(tlog: Path) -> dict[int, FloatArray]:
    """[K,3] (read at, our s; time_boot_ms, vehicle s; climb, m/s) per vehicle in a tlog."""
    log = mavutil.mavlink_connection(str(tlog), dialect="ardupilotmega")
    rows: dict[int, list[tuple[float, float, float]]] = {}
    while (msg := log.recv_match(type="GLOBAL_POSITION_INT", blocking=False)) is not None:
        rows.setdefault(msg.get_srcSystem(), []).append(
            (msg._timestamp, msg.time_boot_ms / 1000.0, -msg.vz / 100.0)
        )
    return {vid: np.array(r, dtype=float) for vid, r in rows.items()}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog="python -m gcs_ppf.tools.telemetry_timing", description=__doc__.split("\n\n")[0]
    )
    parser.add_argument("run", type=Path, help="a run's directory (a campaign's, fly_check's)")
    args = parser.parse_args(argv)
    tlogs = sorted(args.run.glob("tlogs/*.tlog"))
    if not tlogs:
        parser.error(f"no tlogs/*.tlog under {args.run}")
    print(f"{'vehicle':>7}{'rate':>7}   late, vehicle s p50 / p90 / p99   p90 in altitude")
    for tlog in tlogs:
        for vid, r in sorted(positions_read(tlog).items()):
            if len(r) < 3:
                continue
            lag = reading_lag(r[:, 0], r[:, 1])
            climb = float(np.median(np.abs(r[:, 2])))
            cells = " / ".join(f"{x:.3f}" for x in lag.late_s)
            print(f"{vid:>7}{lag.rate:>7.2f}   {cells:>30}   {lag.late_s[1] * climb:8.1f} m")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
