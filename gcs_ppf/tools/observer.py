"""An independent flight observer: where the vehicles really flew, and how safely, judged alone.

Pymavlink on each vehicle's own port records its GLOBAL_POSITION_INT; separation and
clearance are judged from that record only.  It shares nothing with the service that keeps
the invariants: no state, no telemetry decoding, no planner — only the mission document and
the frames (``gcs_ppf.mission``, ``gcs_ppf.geodesy``, ``gcs_ppf.frames``). The integration
tests and the closed-loop campaign (``gcs_ppf.tools.campaign``) judge flights with it.
"""

from __future__ import annotations

import random
import socket
import threading
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from numpy.typing import NDArray
from pymavlink import mavutil

from gcs_ppf.geodesy import geodetic_to_enu
from gcs_ppf.mission import Mission, zone_clearances_m, zone_footprint

FloatArray = NDArray[np.float64]

#: The observer's MAVLink system id: neither a vehicle's nor the service's (255).
OBSERVER_SYSID = 201
#: MAV_SYS_STATUS_PREARM_CHECK in SYS_STATUS health (ArduPilot).
PREARM_OK = 1 << 28
#: Telemetry gap (vehicle s) beyond which a track is not interpolated across.
MAX_GAP_S = 2.0


NO_FIX_E7 = 100_000
"""A position within 0.01° (1e-7° units) of 0°, 0° is none: an autopilot reports there
before it has one (ArduPlane 4.7: lat 3003, lon −696 while waiting for its GPS).  The
service has its own (``telemetry.NULL_ISLAND_DEG``): this judge shares nothing with it."""
PORT_OFFSETS = (0, 1, 2, 3)
"""The ports an instance takes from its base P + 10·i: ArduPilot's SITL binds SERIAL0,
SERIAL1 and SERIAL2 at +0, +2 and +3 (and +1 is kept free as its own layout does)."""
LOWEST_PORT = 20000
"""Blocks are taken from here up to the kernel's ephemeral range."""
_HANDED_OUT: set[int] = set()
"""Every port ``free_port`` and ``free_port_block`` have returned in this process: free when
looked at is not free once a block is handed out and not yet bound.  A test took a block
of 20 for the SITL, then one port for the service's API, which was free because the
SITL had not bound it yet: the API got the SITL's second vehicle port, and the SITL
exited with "address already in use" (``test_signing``, once in a ``make test``)."""


def _take(ports: list[int]) -> bool:
    """Whether every one of ``ports`` is free on 127.0.0.1 (TCP and UDP) and has not been
    handed out before; if so they are handed out now."""
    if _HANDED_OUT.intersection(ports):
        return False
    try:
        for port in ports:
            for kind in (socket.SOCK_STREAM, socket.SOCK_DGRAM):
                with socket.socket(socket.AF_INET, kind) as t:
                    t.bind(("127.0.0.1", port))
    except OSError:
        return False
    _HANDED_OUT.update(ports)
    return True


def ephemeral_ports() -> tuple[int, int]:
    """The range the kernel takes outgoing connections' local ports from."""
    try:
        low, high = Path("/proc/sys/net/ipv4/ip_local_port_range").read_text().split()
        return int(low), int(high)
    except (OSError, ValueError):
        return 32768, 60999


def free_port_block(span: int, offsets: Sequence[int] = PORT_OFFSETS) -> int:
    """A base port P with every P + 10·k + o free on 127.0.0.1 (k = 0 … span / 10, o in
    ``offsets``) and not handed out before (``_HANDED_OUT``), below the ephemeral range
    (best effort: free when looked at).  Taken
    from the ephemeral range and checked at P + 10·k only, a block collided with an
    outgoing connection's port: "bind failed on port … Address already in use", and one
    of five ArduPlane instances exited before its ports were up (session 5)."""
    low = LOWEST_PORT
    high = ephemeral_ports()[0] - span - max(offsets) - 1
    rng = random.Random()
    for _ in range(200):
        base = rng.randrange(low, max(high, low + 1))
        if _take([base + k + o for k in range(0, span + 1, 10) for o in offsets]):
            return base
    raise RuntimeError("no free port block")


def free_port() -> int:
    """One port free on 127.0.0.1 for TCP and UDP, below the ephemeral range.  A port the
    kernel handed out for ``bind(0)`` came from the ephemeral range and was taken by an
    outgoing connection (the browser driver's) before the service bound it: "address
    already in use" (CI)."""
    low = LOWEST_PORT
    high = ephemeral_ports()[0] - 1
    rng = random.Random()
    for _ in range(200):
        port = rng.randrange(low, high)
        if _take([port]):
            return port
    raise RuntimeError("no free port")


@dataclass
class Record:
    """What the observer heard from one vehicle.  ``pos`` rows: (arrival wall time s
    (``time.time()``), time_boot_ms, lat deg, lon deg, alt AMSL m, height above home m);
    ``texts``: (the latest time_boot_ms heard before it, text); ``modes``: (the same,
    HEARTBEAT custom_mode) at each change of mode."""

    pos: list[tuple[float, int, float, float, float, float]] = field(default_factory=list)
    texts: list[tuple[int, str]] = field(default_factory=list)
    modes: list[tuple[int, int]] = field(default_factory=list)
    prearm_ok: bool = False


class Observer:
    """One pymavlink connection per vehicle (``ports``: system id → TCP port on 127.0.0.1),
    a thread each, recording GLOBAL_POSITION_INT, STATUSTEXT, the HEARTBEAT's mode and the
    pre-arm health of SYS_STATUS.  With ``request_streams`` it asks the vehicle on that port for
    GLOBAL_POSITION_INT at 10 Hz and SYS_STATUS at 1 Hz (SET_MESSAGE_INTERVAL applies to the
    port it arrives on: real ArduPlane) until positions flow; the built-in SITL streams them
    to every client anyway.  It sends nothing else."""

    def __init__(
        self, ports: dict[int, int], *, sysid: int = OBSERVER_SYSID, request_streams: bool = False
    ) -> None:
        self.records = {vid: Record() for vid in ports}
        self._sysid = sysid
        self._request = request_streams
        self._stop = threading.Event()
        self._threads = [
            threading.Thread(target=self._run, args=(vid, port), daemon=True)
            for vid, port in ports.items()
        ]

    def _run(self, vid: int, port: int) -> None:
        rec = self.records[vid]
        conn = mavutil.mavlink_connection(
            f"tcp:127.0.0.1:{port}", source_system=self._sysid, source_component=191
        )
        last_pos = asked = 0.0
        tbm = 0
        try:
            while not self._stop.is_set():
                now = time.monotonic()
                if self._request and now - last_pos > 1.0 and now - asked > 1.0:
                    asked = now
                    conn.mav.heartbeat_send(6, 8, 0, 0, 0)  # a GCS, MAV_AUTOPILOT_INVALID
                    for msg_id, interval_us in ((33, 100_000), (1, 1_000_000)):
                        conn.mav.command_long_send(
                            vid, 1, 511, 0, msg_id, interval_us, 0, 0, 0, 0, 0
                        )
                msg = conn.recv_match(
                    type=["GLOBAL_POSITION_INT", "STATUSTEXT", "SYS_STATUS", "HEARTBEAT"],
                    blocking=True,
                    timeout=0.2,
                )
                if msg is None or msg.get_srcSystem() != vid:
                    continue
                kind = msg.get_type()
                if kind == "GLOBAL_POSITION_INT":
                    if abs(msg.lat) < NO_FIX_E7 and abs(msg.lon) < NO_FIX_E7:
                        continue  # no position yet
                    last_pos, tbm = time.monotonic(), int(msg.time_boot_ms)
                    rec.pos.append(
                        (
                            time.time(),
                            tbm,
                            msg.lat * 1e-7,
                            msg.lon * 1e-7,
                            msg.alt * 1e-3,
                            msg.relative_alt * 1e-3,
                        )
                    )
                elif kind == "STATUSTEXT":
                    rec.texts.append((tbm, str(msg.text)))
                elif kind == "HEARTBEAT":
                    if not rec.modes or rec.modes[-1][1] != msg.custom_mode:
                        rec.modes.append((tbm, int(msg.custom_mode)))
                else:
                    rec.prearm_ok = bool(msg.onboard_control_sensors_health & PREARM_OK)
        finally:
            conn.close()

    def latest_boot_ms(self) -> dict[int, int]:
        """Each vehicle's latest time_boot_ms heard (0 before the first)."""
        return {v: (r.pos[-1][1] if r.pos else 0) for v, r in self.records.items()}

    def clocks(self) -> dict[int, FloatArray]:
        """Per vehicle, [K,2] rows of (our wall-clock s, vehicle s) of its samples."""
        return {
            v: np.array([(p[0], p[1] * 1e-3) for p in r.pos], dtype=float).reshape(-1, 2)
            for v, r in self.records.items()
        }

    def __enter__(self) -> Observer:
        for t in self._threads:
            t.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self._stop.set()
        for t in self._threads:
            t.join(timeout=5)


# ---- tracks ------------------------------------------------------------------------------
def tracks_enu(obs: Observer, mission: Mission) -> dict[int, FloatArray]:
    """Per vehicle, [K,5] rows of (vehicle time s, x, y, z, height above home) in the
    mission's ICS, on each vehicle's own clock (the built-in SITL's vehicles share one)."""
    out = {}
    for vid, rec in obs.records.items():
        out[vid] = np.array(
            [
                (tbm / 1000.0, *geodetic_to_enu(la, lo, al, mission.origin), h)
                for _, tbm, la, lo, al, h in rec.pos
            ],
            dtype=float,
        ).reshape(-1, 5)
    return out


def emission_wall_s(
    wall_s: FloatArray, boot_ms: FloatArray, speedup: float, window: int = 50
) -> FloatArray:
    """When each sample left its vehicle, on the observer's wall clock, for vehicles that
    each keep their own boot clock (one ArduPilot instance each): a sample arrives after it
    was sent (TCP delivers in bursts), so the earliest time consistent with the samples
    after it (each dated back along its boot clock at ``speedup``) is taken."""
    out = wall_s.copy()
    for k in range(1, window):
        later = wall_s[k:] - (boot_ms[k:] - boot_ms[:-k]) / (1000.0 * speedup)
        out[:-k] = np.minimum(out[:-k], later)
    return out


def tracks_on_common_clock(
    obs: Observer, mission: Mission, t0_wall: float, speedup: float
) -> dict[int, FloatArray]:
    """Per vehicle [K,5] rows of (vehicle seconds since ``t0_wall`` (``time.time()``) on the
    common clock, x, y, z in the mission's ICS, height above home) from ``t0_wall`` on: the
    format of ``tracks_enu`` for vehicles whose boot clocks differ."""
    out = {}
    for vid, rec in obs.records.items():
        rows = np.array(rec.pos, dtype=float).reshape(-1, 6)
        t = (emission_wall_s(rows[:, 0], rows[:, 1], speedup) - t0_wall) * speedup
        rows, t = rows[t >= 0.0], t[t >= 0.0]
        enu = [geodetic_to_enu(la, lo, al, mission.origin) for la, lo, al in rows[:, 2:5]]
        out[vid] = np.column_stack([t, np.array(enu).reshape(-1, 3), rows[:, 5]])
    return out


def closest_pass(track: FloatArray, point: FloatArray) -> float:
    """Smallest distance from ``point`` to the polyline of ``track`` positions."""
    p = track[:, 1:4]
    if len(p) == 1:
        return float(np.linalg.norm(p[0] - point))
    a, b = p[:-1], p[1:]
    seg = b - a
    length2 = np.maximum((seg**2).sum(axis=1), 1e-12)
    s = np.clip(((point - a) * seg).sum(axis=1) / length2, 0.0, 1.0)
    return float(np.linalg.norm(a + s[:, None] * seg - point, axis=1).min())


def resample(tracks: dict[int, FloatArray], t: FloatArray) -> FloatArray:
    """Positions [T,N,3] of every vehicle (sorted ids) at common times t (linear
    interpolation; held constant outside a track)."""
    ids = sorted(tracks)
    return np.stack(
        [
            np.stack([np.interp(t, tracks[i][:, 0], tracks[i][:, c]) for c in (1, 2, 3)], axis=1)
            for i in ids
        ],
        axis=1,
    )


def observed_at(
    track: FloatArray, t: FloatArray, max_gap_s: float = MAX_GAP_S
) -> NDArray[np.bool_]:
    """[T] mask: the vehicle was heard around each time of ``t`` (inside its track, between
    samples at most ``max_gap_s`` apart), so an interpolated position there is real."""
    ts = track[:, 0]
    if len(ts) == 0:
        return np.zeros(t.shape, dtype=bool)
    k = np.searchsorted(ts, t, side="right")
    before = ts[np.clip(k - 1, 0, len(ts) - 1)]
    after = ts[np.clip(k, 0, len(ts) - 1)]
    inside = (t >= ts[0]) & (t <= ts[-1])
    mask: NDArray[np.bool_] = inside & ((after - before <= max_gap_s) | (t == ts[-1]))
    return mask


HEADING_WINDOW_S = 1.0
"""The leader's flight-path attitude is taken over this window of its track (s)."""


def slot_errors(
    mission: Mission, tracks: dict[int, FloatArray], t: FloatArray
) -> dict[int, FloatArray]:
    """Each wingman's position less its local target point (Eq. 6) at the times ``t``
    [K], from the observer's tracks, in the leader's flight-path frame: [K,3] forward,
    left, up (m), the axes of the slot itself (G − P₀ = s_x·forward + s_y·left + s_z·up).
    Forward errors are the speed loop's, left the course's, up the climb's (and the
    leader's flight-path angle's: a slot d behind swings d·Δθ)."""
    ids = sorted(tracks)
    pos = resample(tracks, t)
    lead = ids.index(mission.leader.id)
    # the leader's flight path over a second: a gradient over 0.1 s of positions dated by
    # their arrival put its yaw off by degrees (metres at the slots) on a busy machine
    half = HEADING_WINDOW_S / 2.0
    vel = (resample(tracks, t + half)[:, lead] - resample(tracks, t - half)[:, lead]) / (2 * half)
    pitch = np.arctan2(vel[:, 2], np.hypot(vel[:, 0], vel[:, 1]))
    yaw = np.arctan2(vel[:, 1], vel[:, 0])
    cp, sp, cy, sy = np.cos(pitch), np.sin(pitch), np.cos(yaw), np.sin(yaw)
    forward = np.stack([cp * cy, cp * sy, sp], axis=1)
    left = np.stack([-sy, cy, np.zeros_like(cy)], axis=1)
    up = np.stack([-sp * cy, -sp * sy, cp], axis=1)
    errors = {}
    for w in mission.wingmen:
        assert w.slot is not None
        rel = pos[:, ids.index(w.id)] - pos[:, lead]
        local = np.stack([(rel * axis).sum(axis=1) for axis in (forward, left, up)], axis=1)
        errors[w.id] = local - np.array(w.slot)
    return errors


def slot_distances(
    mission: Mission, tracks: dict[int, FloatArray], t: FloatArray
) -> dict[int, FloatArray]:
    """Each wingman's distance to its local target point (Eq. 6, the leader's flight-path
    attitude from its track) at the times ``t``, from the observer's tracks."""
    return {vid: np.linalg.norm(e, axis=1) for vid, e in slot_errors(mission, tracks, t).items()}


def formation_offsets(
    mission: Mission, tracks: dict[int, FloatArray], start_s: float, duration_s: float
) -> tuple[dict[int, float], float]:
    """From the observer's tracks: each wingman's smallest distance to its local target
    point over [start_s, start_s + duration_s], and the smallest over time of the worst
    wingman's distance (within the target accuracy: formed)."""
    t = np.arange(start_s, start_s + duration_s, 0.1)
    offsets = slot_distances(mission, tracks, t)
    worst = np.max(np.stack(list(offsets.values())), axis=0)
    return {vid: float(d.min()) for vid, d in offsets.items()}, float(worst.min())


def longest_formed_s(
    mission: Mission, tracks: dict[int, FloatArray], start_s: float, duration_s: float
) -> float:
    """The longest time (s) every wingman stayed within the target accuracy of its local
    target point at once, over [start_s, start_s + duration_s]: how long the formation held."""
    step = 0.1
    t = np.arange(start_s, start_s + duration_s, step)
    offsets = slot_distances(mission, tracks, t)
    worst = np.max(np.stack(list(offsets.values())), axis=0)
    return held_s(worst, mission.limits.target_accuracy, step)


def held_s(worst_m: FloatArray, accuracy_m: float, step_s: float) -> float:
    """The longest stretch (s) of the worst wingman's distances ``worst_m`` (``step_s``
    apart) within ``accuracy_m``."""
    longest = run = 0
    for f in worst_m <= accuracy_m:
        run = run + 1 if f else 0
        longest = max(longest, run)
    return longest * step_s


# ---- judging -----------------------------------------------------------------------------
@dataclass(frozen=True)
class Judgement:
    """What the observer saw in a window of vehicle time (all distances in metres).

    ``min_separation_m``: closest centre-to-centre distance of two vehicles both heard
    then (None: never two); ``closest_pair`` their ids.  ``clearance_m``: per vehicle, its
    closest approach to any obstacle's or zone's surface (a zone's free side positive, as
    ``mission.zone_clearance``; None without either), with moving
    obstacles placed at their positions ``t − run_start_s`` after the run's start.
    ``lowest_m``: per vehicle, its lowest height above home once it had been
    ``ground_keepout_m`` above it (None if it never was).  ``leader_to_target_m``: the
    leader's closest pass by the target."""

    window_s: tuple[float, float]
    samples: int
    min_separation_m: float | None
    closest_pair: tuple[int, int] | None
    clearance_m: dict[int, float | None]
    lowest_m: dict[int, float | None]
    leader_to_target_m: float | None

    def min_clearance_m(self, exclude: Sequence[int] = ()) -> float | None:
        """Smallest obstacle clearance over the vehicles not in ``exclude``."""
        values = [c for v, c in self.clearance_m.items() if c is not None and v not in exclude]
        return min(values) if values else None


def vehicle_time_at(clock: FloatArray, wall_s: float, window_s: float = 0.3) -> float:
    """A vehicle's clock at our wall time ``wall_s``, from its samples ([K,2] rows of
    (arrival wall s, vehicle s), ``Observer.clocks``): each sample that arrived in the
    ``window_s`` before, its stamp carried on at the clock's rate over the track, is a lower
    bound (it arrived after it was stamped), and the largest is the one read soonest.
    (Interpolating the arrivals instead puts the clock late by however late a busy observer
    read it: at ×10, 20 ms of ours is 0.2 s of the vehicle's.)"""
    rate = (clock[-1, 1] - clock[0, 1]) / max(clock[-1, 0] - clock[0, 0], 1e-9)
    near = clock[(clock[:, 0] <= wall_s) & (clock[:, 0] >= wall_s - window_s)]
    if len(near) == 0:
        return float(np.interp(wall_s, clock[:, 0], clock[:, 1]))
    return float(np.max(near[:, 1] + (wall_s - near[:, 0]) * rate))


def judge(
    mission: Mission,
    tracks: dict[int, FloatArray],
    start_s: float,
    end_s: float,
    *,
    run_start_s: float | None = None,
    dt_s: float = 0.05,
    ground_keepout_m: float | None = None,
) -> Judgement:
    """Separation, obstacle clearance and height over [start_s, end_s] of vehicle time, at
    ``dt_s`` steps, from the positions of the vehicles heard at each moment (a vehicle that
    fell silent counts until its last sample)."""
    ids = sorted(tracks)
    t = np.arange(start_s, end_s + 1e-9, dt_s)
    run0 = start_s if run_start_s is None else run_start_s
    pos = np.zeros((len(t), len(ids), 3))
    heard = np.zeros((len(t), len(ids)), dtype=bool)
    for k, vid in enumerate(ids):
        tr = tracks[vid]
        if len(tr) == 0:
            continue
        heard[:, k] = observed_at(tr, t)
        for c in range(3):
            pos[:, k, c] = np.interp(t, tr[:, 0], tr[:, 1 + c])
    sep: float | None = None
    pair: tuple[int, int] | None = None
    for a in range(len(ids)):
        for b in range(a + 1, len(ids)):
            both = heard[:, a] & heard[:, b]
            if not both.any():
                continue
            d = float(np.linalg.norm(pos[both, a] - pos[both, b], axis=1).min())
            if sep is None or d < sep:
                sep, pair = d, (ids[a], ids[b])
    clearance: dict[int, float | None] = {}
    footprints = [(z, zone_footprint(z, mission.origin)) for z in mission.zones]
    for k, vid in enumerate(ids):
        mask = heard[:, k]
        if not (mission.obstacles or footprints) or not mask.any():
            clearance[vid] = None
            continue
        p, tk = pos[mask, k], t[mask]
        spheres = [
            float(
                (
                    np.linalg.norm(
                        p - (np.array(o.center) + np.outer(tk - run0, np.array(o.velocity))), axis=1
                    )
                    - o.radius
                ).min()
            )
            for o in mission.obstacles
        ]
        zones = [float(zone_clearances_m(z, f, p).min()) for z, f in footprints]
        clearance[vid] = min(spheres + zones)
    keepout = (
        mission.limits.safe_distance_obstacle if ground_keepout_m is None else ground_keepout_m
    )
    lowest: dict[int, float | None] = {}
    for vid in ids:
        tr = tracks[vid]
        h = tr[(tr[:, 0] >= start_s) & (tr[:, 0] <= end_s), 4] if len(tr) else np.zeros(0)
        up = np.flatnonzero(h >= keepout)
        lowest[vid] = float(h[up[0] :].min()) if up.size else None
    lead = tracks.get(mission.leader.id)
    to_target = None
    if lead is not None and len(lead):
        seg = lead[(lead[:, 0] >= start_s) & (lead[:, 0] <= end_s)]
        if len(seg):
            to_target = closest_pass(seg, np.array(mission.target))
    return Judgement(
        (start_s, end_s), int(heard.any(axis=1).sum()), sep, pair, clearance, lowest, to_target
    )
