"""Service settings: command-line options over environment variables (``GCS_PPF_*``)."""

from __future__ import annotations

import ipaddress
import re
from pathlib import Path
from typing import Literal

from pydantic import Field, PrivateAttr, SecretStr, field_validator, model_validator
from pydantic_settings import BaseSettings, SettingsConfigDict

from gcs_ppf.mavlink.codec import signing_key_from_text
from gcs_ppf.service.links import parse_forward_url
from gcs_ppf.tokens import TokenEntry, load_token_file

HOST = re.compile(r"[A-Za-z0-9_.:-]{1,253}")  # a name, an IPv4 or an IPv6 address


class Settings(BaseSettings):
    """How the ground-station service runs; every field can be set as ``GCS_PPF_<NAME>``
    (``GCS_PPF_LINKS='["tcp:127.0.0.1:5760"]'``)."""

    model_config = SettingsConfigDict(
        env_prefix="GCS_PPF_", extra="forbid", hide_input_in_errors=True
    )

    host: str = "127.0.0.1"
    port: int = Field(default=8000, ge=1, le=65535)
    db: Path = Path("gcs_ppf.db")
    links: list[str] = Field(default_factory=list)
    forward: list[str] = Field(
        default_factory=list,
        description="other ground stations to relay every vehicle's frames to and theirs "
        "from, as mavlink-router does: udpout:HOST:PORT (QGroundControl listens on udp 14550), "
        "udpin:HOST:PORT, tcpin:HOST:PORT (ground stations connect)",
    )
    system_id: int = Field(default=255, ge=1, le=255, description="the GCS's MAVLink id")
    tick_hz: float = Field(default=10.0, gt=0.0, le=100.0, description="per vehicle second")
    lookahead_s: float = Field(default=3.0, gt=0.0, le=30.0)
    planning_margin_m: float | None = Field(
        default=None,
        ge=0.0,
        description="added to both safe distances when planning online; unset: v_max × the "
        "vehicles' response lag (the roll-in, 4 × RLL2SRV_TCONST, or without it GUIDED_P's "
        "heading time constant; + a telemetry interval), at most 100 m, and 100 m for a "
        "vehicle that does not report GUIDED_P",
    )
    guidance: Literal["course", "point"] = Field(
        default="course",
        description="fly each vehicle by course and altitude (MAV_CMD_GUIDED_CHANGE_HEADING/"
        "_ALTITUDE, ArduPlane built with AP_PLANE_OFFBOARD_GUIDED_SLEW_ENABLED) or by a guided "
        "point (DO_REPOSITION, any ArduPlane)",
    )
    carrot_m: float = Field(default=1500.0, gt=0.0, description="guided point beyond the plan")
    planner_dt_s: float = Field(default=0.02, gt=0.0, le=0.5)
    guard_horizon_s: float | None = Field(
        default=None,
        ge=0.0,
        le=60.0,
        description="separation guard look-ahead (0: off); unset: the time to climb or sink "
        "the safe distance at TECS_CLMB_MAX/TECS_SINK_MAX plus the response lag, at least 4 s",
    )
    guard_margin_m: float | None = Field(
        default=None,
        ge=0.0,
        description="the guard acts below safe_distance_uav plus this; unset: each vehicle's "
        "speed × its response lag, at most 50 m (50 m without GUIDED_P)",
    )
    guard_resolution_m: float | None = Field(
        default=None,
        gt=0.0,
        description="altitude change of a vertical resolution; unset: what TECS climbs "
        "(sinks) within the horizon, at most 150 m (150 m without TECS limits)",
    )
    takeoff_alt_m: float = Field(
        default=50.0, gt=0.0, description="TKOFF_ALT given to vehicles that start on the ground"
    )
    takeoff_dist_m: float = Field(
        default=1000.0,
        gt=0.0,
        description="TKOFF_DIST given to them: they climb straight out along their runways "
        "towards a point this far ahead instead of circling 200 m ahead (ArduPlane's default), "
        "so the formation starts as the plan assumes",
    )
    prearm_timeout_s: float = Field(
        default=60.0,
        ge=0.0,
        le=600.0,
        description="how long (our seconds) a start waits for each vehicle's pre-arm checks "
        "and retries an arm refused for a reason that may clear (real ArduPlane: some seconds "
        "after boot while the EKF settles); 0: arm at once, or fail naming the reasons",
    )
    failsafe_rtl_altitude: bool = Field(
        default=True,
        description="at each launch, set every vehicle's RTL_ALTITUDE over every keep-out of "
        "the mission, one holding level apart (guidance.failsafe): the altitude its own GCS "
        "failsafe flies home at if the service dies; false: leave the vehicles' own",
    )
    fences: bool = Field(
        default=True,
        description="at each launch, upload the mission's zones as every vehicle's own fence "
        "(verified, FENCE_ENABLE 1), and restore what it had after the run",
    )
    fence_action: int = Field(
        default=1,
        ge=0,
        le=7,
        description="FENCE_ACTION given with the fence: 1 RTL (ArduPlane's default), 0 report "
        "only, 6 guided to the fence's return point",
    )
    fence_footprints: bool = Field(
        default=False,
        description="upload also the footprints of exclusion zones with a floor or a ceiling "
        "(a fence has neither: the vehicle may not fly over or under them then)",
    )
    vehicle_timeout_s: float = Field(
        default=5.0, gt=0.0, description="silence, in the vehicle's own seconds, that makes it lost"
    )
    starvation_allowance_s: float = Field(
        default=0.5,
        ge=0.0,
        le=10.0,
        description="seconds of the service's own time it may be starved of CPU between two "
        "ticks: every command sent must stay clear of every keep-out for that long too, in "
        "the vehicles' time (× the SITL's speed-up; measured: 0.3-0.56 s stalls in 5 of 6 "
        "campaign runs at x10, load about 4)",
    )
    heartbeat_hz: float = Field(default=1.0, gt=0.0)
    telemetry_sample_hz: float = Field(default=2.0, gt=0.0)
    stream_rate_hz: float = Field(default=10.0, gt=0.0)
    tlog_dir: Path | None = Path("tlogs")
    tokens: list[TokenEntry] = Field(
        default_factory=list,
        description="API bearer tokens, hashed: [{id, sha256, scopes}] (`gcs-ppf token` makes "
        "one); with none here nor in token_file the API is open, on loopback only",
    )
    token_file: Path | None = Field(
        default=None, description="a JSON file of more such entries (`gcs-ppf token --file`)"
    )
    link_allow: list[str] = Field(
        default_factory=list,
        description="hosts (names or addresses) and networks (CIDR) that POST /links may "
        "connect to besides loopback, and serial devices it may open (absolute paths, shell "
        "patterns allowed: /dev/ttyUSB*); none by default",
    )
    audit_log: Path | None = Field(
        default=None,
        description="JSON lines, one per command request; unset: beside the database "
        "(<db>.audit.jsonl), none for an in-memory database",
    )
    max_body_bytes: int = Field(default=1_000_000, ge=1_000, description="request bodies (413)")
    max_vehicles: int = Field(default=100, ge=1, le=1000, description="vehicles of a mission")
    max_obstacles: int = Field(default=1000, ge=0, le=10_000, description="obstacles of one")

    @field_validator("forward")
    @classmethod
    def _forward_urls(cls, urls: list[str]) -> list[str]:
        for url in urls:
            parse_forward_url(url)  # its ValueError names the URL
        return urls

    @field_validator("link_allow")
    @classmethod
    def _allowed_hosts(cls, entries: list[str]) -> list[str]:
        for entry in entries:
            if entry.startswith("/"):
                continue  # a serial device's path, or a pattern of them
            if "/" in entry:
                try:
                    ipaddress.ip_network(entry, strict=False)
                except ValueError:
                    raise ValueError(
                        f"{entry!r} is not a network (CIDR, e.g. 10.0.0.0/24)"
                    ) from None
            elif not HOST.fullmatch(entry.strip("[]")):
                raise ValueError(f"{entry!r} is not a host name or address")
        return entries

    def api_tokens(self) -> list[TokenEntry]:
        """``tokens`` and those of ``token_file`` (raises ``TokenFileError``)."""
        extra = [] if self.token_file is None else load_token_file(self.token_file)
        return [*self.tokens, *extra]

    def audit_path(self) -> Path | None:
        if self.audit_log is not None:
            return self.audit_log
        if str(self.db) == ":memory:":
            return None
        return self.db.with_name(self.db.stem + ".audit.jsonl")

    signing_key: SecretStr | None = Field(
        default=None,
        description="MAVLink 2 signing key: 64 hex digits, or a passphrase hashed with SHA-256 "
        "(as MAVProxy's `signing setup`); set GCS_PPF_SIGNING_KEY or signing_key_file, never "
        "a command-line argument (ps shows those). With a key every frame sent is signed and "
        "unsigned or wrongly signed frames are refused, except on unsigned_links",
    )
    signing_key_file: Path | None = Field(
        default=None, description="a file holding the signing key (hex or passphrase)"
    )
    unsigned_links: list[str] = Field(
        default_factory=list,
        description="link URLs on which unsigned frames are accepted although signing is on "
        "(vehicles that do not sign); wrongly signed frames are refused there too",
    )
    _signing_key: bytes | None = PrivateAttr(default=None)

    @model_validator(mode="after")
    def _load_signing_key(self) -> Settings:
        if self.signing_key is not None and self.signing_key_file is not None:
            raise ValueError("signing_key and signing_key_file: set one of them, not both")
        text: str | None = None
        if self.signing_key is not None:
            text = self.signing_key.get_secret_value()
        elif self.signing_key_file is not None:
            try:
                text = self.signing_key_file.read_text(encoding="utf-8")
            except (OSError, UnicodeDecodeError) as exc:
                reason = getattr(exc, "strerror", None) or type(exc).__name__
                raise ValueError(
                    f"signing_key_file: cannot read {self.signing_key_file}: {reason}"
                ) from None
        if text is not None:
            try:
                self._signing_key = signing_key_from_text(text)
            except ValueError as exc:
                field = "signing_key" if self.signing_key is not None else "signing_key_file"
                raise ValueError(f"{field}: {exc}") from None
        return self

    @property
    def signing_key_bytes(self) -> bytes | None:
        """The 32-byte MAVLink signing key, or None: no signing."""
        return self._signing_key
