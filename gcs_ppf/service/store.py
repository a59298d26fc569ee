"""Persistence: missions, runs, events and sampled telemetry in one SQLite file.

The schema is created and migrated by the service itself (``PRAGMA user_version`` counts
the migrations applied).  Writes are small and synchronous; every change commits at once,
so a restarted service finds every uploaded mission and every run as it was left.
"""

from __future__ import annotations

import json
import sqlite3
import time
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from gcs_ppf.mission import Mission

MIGRATIONS: tuple[str, ...] = (
    """
    CREATE TABLE missions (
        id INTEGER PRIMARY KEY AUTOINCREMENT,
        name TEXT NOT NULL,
        document TEXT NOT NULL,
        created_s REAL NOT NULL
    );
    CREATE TABLE runs (
        id INTEGER PRIMARY KEY AUTOINCREMENT,
        mission_id INTEGER NOT NULL REFERENCES missions(id),
        state TEXT NOT NULL,
        started_s REAL NOT NULL,
        ended_s REAL,
        outcome TEXT,
        summary TEXT
    );
    CREATE TABLE events (
        id INTEGER PRIMARY KEY AUTOINCREMENT,
        run_id INTEGER NOT NULL REFERENCES runs(id),
        mission_time_s REAL,
        wall_s REAL NOT NULL,
        kind TEXT NOT NULL,
        vehicle_id INTEGER,
        detail TEXT
    );
    CREATE TABLE telemetry (
        run_id INTEGER NOT NULL REFERENCES runs(id),
        mission_time_s REAL NOT NULL,
        vehicle_id INTEGER NOT NULL,
        lat_deg REAL, lon_deg REAL, alt_amsl_m REAL,
        x_m REAL, y_m REAL, z_m REAL, speed_m_s REAL
    );
    CREATE INDEX events_by_run ON events(run_id);
    CREATE INDEX telemetry_by_run ON telemetry(run_id, mission_time_s);
    """,
)


# (mission_time_s, vehicle_id, lat_deg, lon_deg, alt_amsl_m, x_m, y_m, z_m, speed_m_s)
TelemetryRow = tuple[float, int, float, float, float, float, float, float, float]


@dataclass(frozen=True)
class StoredMission:
    id: int
    name: str
    mission: Mission
    created_s: float


@dataclass(frozen=True)
class StoredRun:
    id: int
    mission_id: int
    state: str
    started_s: float
    ended_s: float | None
    outcome: str | None
    summary: dict[str, Any] | None


@dataclass(frozen=True)
class StoredEvent:
    run_id: int
    mission_time_s: float | None
    wall_s: float
    kind: str
    vehicle_id: int | None
    detail: dict[str, Any] | None


class Store:
    """The service's SQLite database (``:memory:`` for tests)."""

    def __init__(self, path: str | Path) -> None:
        if str(path) != ":memory:":
            Path(path).parent.mkdir(parents=True, exist_ok=True)
        self._db = sqlite3.connect(str(path), check_same_thread=False, isolation_level=None)
        self._db.execute("PRAGMA foreign_keys = ON")
        self._db.execute("PRAGMA journal_mode = WAL")
        self._db.execute("PRAGMA synchronous = NORMAL")  # WAL: no fsync per commit
        self.migrate()

    def close(self) -> None:
        self._db.close()

    @contextmanager
    def _transaction(self) -> Iterator[sqlite3.Connection]:
        self._db.execute("BEGIN")
        try:
            yield self._db
        except BaseException:
            self._db.execute("ROLLBACK")
            raise
        self._db.execute("COMMIT")

    @property
    def schema_version(self) -> int:
        return int(self._db.execute("PRAGMA user_version").fetchone()[0])

    def migrate(self) -> None:
        """Apply the migrations this database has not seen yet."""
        for version in range(self.schema_version, len(MIGRATIONS)):
            with self._transaction() as db:
                for statement in MIGRATIONS[version].split(";"):
                    if statement.strip():
                        db.execute(statement)
                db.execute(f"PRAGMA user_version = {version + 1}")

    # Missions ---------------------------------------------------------------------------
    def add_mission(self, mission: Mission) -> StoredMission:
        now = time.time()
        with self._transaction() as db:
            cur = db.execute(
                "INSERT INTO missions (name, document, created_s) VALUES (?, ?, ?)",
                (mission.name, mission.model_dump_json(), now),
            )
        return StoredMission(int(cur.lastrowid or 0), mission.name, mission, now)

    def replace_mission(self, mission_id: int, mission: Mission) -> StoredMission:
        with self._transaction() as db:
            cur = db.execute(
                "UPDATE missions SET name = ?, document = ? WHERE id = ?",
                (mission.name, mission.model_dump_json(), mission_id),
            )
            if cur.rowcount != 1:
                raise KeyError(mission_id)
        return self.mission(mission_id)

    def mission(self, mission_id: int) -> StoredMission:
        row = self._db.execute(
            "SELECT id, name, document, created_s FROM missions WHERE id = ?", (mission_id,)
        ).fetchone()
        if row is None:
            raise KeyError(mission_id)
        return StoredMission(row[0], row[1], Mission.model_validate_json(row[2]), row[3])

    def missions(self) -> list[StoredMission]:
        rows = self._db.execute("SELECT id FROM missions ORDER BY id").fetchall()
        return [self.mission(r[0]) for r in rows]

    # Runs -------------------------------------------------------------------------------
    def add_run(self, mission_id: int, state: str) -> StoredRun:
        now = time.time()
        with self._transaction() as db:
            cur = db.execute(
                "INSERT INTO runs (mission_id, state, started_s) VALUES (?, ?, ?)",
                (mission_id, state, now),
            )
        return self.run(int(cur.lastrowid or 0))

    def update_run(
        self,
        run_id: int,
        state: str,
        *,
        ended: bool = False,
        outcome: str | None = None,
        summary: dict[str, Any] | None = None,
    ) -> StoredRun:
        with self._transaction() as db:
            db.execute(
                "UPDATE runs SET state = ?, ended_s = COALESCE(?, ended_s), "
                "outcome = COALESCE(?, outcome), summary = COALESCE(?, summary) WHERE id = ?",
                (
                    state,
                    time.time() if ended else None,
                    outcome,
                    json.dumps(summary) if summary is not None else None,
                    run_id,
                ),
            )
        return self.run(run_id)

    def run(self, run_id: int) -> StoredRun:
        row = self._db.execute(
            "SELECT id, mission_id, state, started_s, ended_s, outcome, summary FROM runs "
            "WHERE id = ?",
            (run_id,),
        ).fetchone()
        if row is None:
            raise KeyError(run_id)
        summary = json.loads(row[6]) if row[6] else None
        return StoredRun(row[0], row[1], row[2], row[3], row[4], row[5], summary)

    def runs(self, mission_id: int | None = None) -> list[StoredRun]:
        if mission_id is None:
            rows = self._db.execute("SELECT id FROM runs ORDER BY id").fetchall()
        else:
            rows = self._db.execute(
                "SELECT id FROM runs WHERE mission_id = ? ORDER BY id", (mission_id,)
            ).fetchall()
        return [self.run(r[0]) for r in rows]

    def interrupted_runs(self) -> list[StoredRun]:
        """Runs a previous process left unfinished (it stopped while they flew)."""
        return [r for r in self.runs() if r.ended_s is None]

    # Events and telemetry ----------------------------------------------------------------
    def add_event(
        self,
        run_id: int,
        kind: str,
        *,
        mission_time_s: float | None = None,
        vehicle_id: int | None = None,
        detail: dict[str, Any] | None = None,
    ) -> StoredEvent:
        now = time.time()
        with self._transaction() as db:
            db.execute(
                "INSERT INTO events (run_id, mission_time_s, wall_s, kind, vehicle_id, detail) "
                "VALUES (?, ?, ?, ?, ?, ?)",
                (
                    run_id,
                    mission_time_s,
                    now,
                    kind,
                    vehicle_id,
                    json.dumps(detail) if detail is not None else None,
                ),
            )
        return StoredEvent(run_id, mission_time_s, now, kind, vehicle_id, detail)

    def events(self, run_id: int) -> list[StoredEvent]:
        rows = self._db.execute(
            "SELECT run_id, mission_time_s, wall_s, kind, vehicle_id, detail FROM events "
            "WHERE run_id = ? ORDER BY id",
            (run_id,),
        ).fetchall()
        return [
            StoredEvent(r[0], r[1], r[2], r[3], r[4], json.loads(r[5]) if r[5] else None)
            for r in rows
        ]

    def add_telemetry(self, run_id: int, rows: list[TelemetryRow]) -> None:
        """Rows of (mission_time_s, vehicle_id, lat, lon, alt_amsl, x, y, z, speed)."""
        with self._transaction() as db:
            db.executemany(
                "INSERT INTO telemetry VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?, ?)",
                [(run_id, *r) for r in rows],
            )

    def telemetry(self, run_id: int) -> list[TelemetryRow]:
        """A run's rows (as ``add_telemetry`` took them), by mission time."""
        rows = self._db.execute(
            "SELECT mission_time_s, vehicle_id, lat_deg, lon_deg, alt_amsl_m, x_m, y_m, z_m, "
            "speed_m_s FROM telemetry WHERE run_id = ? ORDER BY mission_time_s, vehicle_id",
            (run_id,),
        ).fetchall()
        return [tuple(r) for r in rows]

    def telemetry_count(self, run_id: int) -> int:
        row = self._db.execute("SELECT COUNT(*) FROM telemetry WHERE run_id = ?", (run_id,))
        return int(row.fetchone()[0])
