"""Persistence: missions, runs, events and sampled telemetry in one SQLite file.

The schema is created and migrated by the service itself (``PRAGMA user_version`` counts
the migrations applied).  Writes are small; every change commits at once, so a restarted
service finds every uploaded mission and every run as it was left.  The two a run makes
every tick, its events and its sampled telemetry, are written behind, in order, by a thread
of the store's own (off the tick's path: at 100 vehicles an event's commit took 1.5 ms, up
to 35 ms, of a tick), and every other call waits for what was queued before it (what one
caller wrote it reads back); ``close`` writes what is still queued (a process killed
outright loses what was queued: milliseconds of events, where a synchronous write lost at
most the one under way).
"""

from __future__ import annotations

import functools
import json
import logging
import queue
import sqlite3
import threading
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Concatenate, ParamSpec, TypeVar

from gcs_ppf.mission import Mission

log = logging.getLogger(__name__)

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
    """
    CREATE TABLE links (
        url TEXT PRIMARY KEY,
        allow_unsigned INTEGER,
        added_s REAL NOT NULL
    );
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


WRITER_IDLE_S = 5.0
"""The writer thread ends after this long without a write (a new one starts with the next)."""

P = ParamSpec("P")
R = TypeVar("R")
Write = Callable[[sqlite3.Connection], None]


def _after_queued(f: Callable[Concatenate[Store, P], R]) -> Callable[Concatenate[Store, P], R]:
    """A call that waits for the writes queued before it, then has the database alone."""

    @functools.wraps(f)
    def wrapped(self: Store, /, *args: P.args, **kwargs: P.kwargs) -> R:
        inside = getattr(self._held, "depth", 0)
        if not inside:  # (inside a call that has the lock, waiting would wait for ever)
            self._queue.join()
        with self._lock:
            self._held.depth = inside + 1
            try:
                return f(self, *args, **kwargs)
            finally:
                self._held.depth = inside

    return wrapped


class Store:
    """The service's SQLite database (``:memory:`` for tests)."""

    def __init__(self, path: str | Path) -> None:
        if str(path) != ":memory:":
            Path(path).parent.mkdir(parents=True, exist_ok=True)
        self._db = sqlite3.connect(str(path), check_same_thread=False, isolation_level=None)
        self._db.execute("PRAGMA foreign_keys = ON")
        self._db.execute("PRAGMA journal_mode = WAL")
        self._db.execute("PRAGMA synchronous = NORMAL")  # WAL: no fsync per commit
        self._lock = threading.RLock()
        self._held = threading.local()  # how deep this thread is in calls that have the lock
        self._queue: queue.Queue[Write | None] = queue.Queue()
        self._writer: threading.Thread | None = None
        self._writer_lock = threading.Lock()  # the writer's start and end, never the database
        self.write_errors = 0
        """Writes behind that failed (logged)."""
        self.migrate()

    def close(self) -> None:
        """Write what is queued, then close."""
        with self._writer_lock:
            writer = self._writer
            if writer is not None:
                self._queue.put(None)
        if writer is not None:
            writer.join()
        self._queue.join()
        self._db.close()

    def _write_behind(self, write: Write) -> None:
        """``write`` queued for the store's writer thread (started when none is running)."""
        with self._writer_lock:
            if self._writer is None:
                self._writer = threading.Thread(
                    target=self._write_queued, name="store-writer", daemon=True
                )
                self._writer.start()
            self._queue.put(write)

    def _write_queued(self) -> None:
        """The writer thread: the queued writes in order, as many as are queued in one
        transaction (one by one when that fails: a failed write is logged, never the
        service's end, and the others are kept), until ``close`` or ``WRITER_IDLE_S``
        without any."""
        while True:
            try:
                first = self._queue.get(timeout=WRITER_IDLE_S)
            except queue.Empty:
                with self._writer_lock:
                    if self._queue.empty():
                        self._writer = None
                        return
                continue
            batch = [first]
            while batch[-1] is not None and len(batch) < 1000 and not self._queue.empty():
                batch.append(self._queue.get_nowait())
            writes = [w for w in batch if w is not None]
            try:
                self._commit(writes)
            finally:
                for _ in batch:
                    self._queue.task_done()
            if batch[-1] is None:
                return

    def _commit(self, writes: list[Write]) -> None:
        if not writes:
            return
        try:
            with self._lock, self._transaction() as db:
                for w in writes:
                    w(db)
            return
        except Exception:
            if len(writes) == 1:
                self.write_errors += 1
                log.exception("store: a queued write failed")
                return
        for w in writes:
            self._commit([w])

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
    @_after_queued
    def schema_version(self) -> int:
        return int(self._db.execute("PRAGMA user_version").fetchone()[0])

    @_after_queued
    def migrate(self) -> None:
        """Apply the migrations this database has not seen yet."""
        for version in range(self.schema_version, len(MIGRATIONS)):
            with self._transaction() as db:
                for statement in MIGRATIONS[version].split(";"):
                    if statement.strip():
                        db.execute(statement)
                db.execute(f"PRAGMA user_version = {version + 1}")

    # Missions ---------------------------------------------------------------------------
    @_after_queued
    def add_mission(self, mission: Mission) -> StoredMission:
        now = time.time()
        with self._transaction() as db:
            cur = db.execute(
                "INSERT INTO missions (name, document, created_s) VALUES (?, ?, ?)",
                (mission.name, mission.model_dump_json(), now),
            )
        return StoredMission(int(cur.lastrowid or 0), mission.name, mission, now)

    @_after_queued
    def replace_mission(self, mission_id: int, mission: Mission) -> StoredMission:
        with self._transaction() as db:
            cur = db.execute(
                "UPDATE missions SET name = ?, document = ? WHERE id = ?",
                (mission.name, mission.model_dump_json(), mission_id),
            )
            if cur.rowcount != 1:
                raise KeyError(mission_id)
        return self.mission(mission_id)

    @_after_queued
    def mission(self, mission_id: int) -> StoredMission:
        row = self._db.execute(
            "SELECT id, name, document, created_s FROM missions WHERE id = ?", (mission_id,)
        ).fetchone()
        if row is None:
            raise KeyError(mission_id)
        return StoredMission(row[0], row[1], Mission.model_validate_json(row[2]), row[3])

    @_after_queued
    def missions(self) -> list[StoredMission]:
        rows = self._db.execute("SELECT id FROM missions ORDER BY id").fetchall()
        return [self.mission(r[0]) for r in rows]

    # Runs -------------------------------------------------------------------------------
    @_after_queued
    def add_run(self, mission_id: int, state: str) -> StoredRun:
        now = time.time()
        with self._transaction() as db:
            cur = db.execute(
                "INSERT INTO runs (mission_id, state, started_s) VALUES (?, ?, ?)",
                (mission_id, state, now),
            )
        return self.run(int(cur.lastrowid or 0))

    @_after_queued
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

    @_after_queued
    def reopen_run(self, run_id: int, state: str) -> StoredRun:
        """An ended run unended again (``state``, no end time, no outcome): resumed."""
        with self._transaction() as db:
            db.execute(
                "UPDATE runs SET state = ?, ended_s = NULL, outcome = NULL WHERE id = ?",
                (state, run_id),
            )
        return self.run(run_id)

    @_after_queued
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

    @_after_queued
    def runs(self, mission_id: int | None = None) -> list[StoredRun]:
        if mission_id is None:
            rows = self._db.execute("SELECT id FROM runs ORDER BY id").fetchall()
        else:
            rows = self._db.execute(
                "SELECT id FROM runs WHERE mission_id = ? ORDER BY id", (mission_id,)
            ).fetchall()
        return [self.run(r[0]) for r in rows]

    @_after_queued
    def interrupted_runs(self) -> list[StoredRun]:
        """Runs a previous process left unfinished (it stopped while they flew)."""
        return [r for r in self.runs() if r.ended_s is None]

    # Links ------------------------------------------------------------------------------
    @_after_queued
    def add_link(self, url: str, allow_unsigned: bool | None) -> None:
        """A link the service was told to open (``POST /links``): opened again on restart."""
        with self._transaction() as db:
            db.execute(
                "INSERT OR REPLACE INTO links (url, allow_unsigned, added_s) VALUES (?, ?, ?)",
                (url, None if allow_unsigned is None else int(allow_unsigned), time.time()),
            )

    @_after_queued
    def remove_link(self, url: str) -> None:
        with self._transaction() as db:
            db.execute("DELETE FROM links WHERE url = ?", (url,))

    @_after_queued
    def links(self) -> list[tuple[str, bool | None]]:
        """(url, allow_unsigned) of every link added and not removed, in the order added."""
        rows = self._db.execute("SELECT url, allow_unsigned FROM links ORDER BY added_s")
        return [(url, None if a is None else bool(a)) for url, a in rows.fetchall()]

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
        row = (
            run_id,
            mission_time_s,
            now,
            kind,
            vehicle_id,
            json.dumps(detail) if detail is not None else None,
        )

        def write(db: sqlite3.Connection) -> None:
            db.execute(
                "INSERT INTO events (run_id, mission_time_s, wall_s, kind, vehicle_id, detail) "
                "VALUES (?, ?, ?, ?, ?, ?)",
                row,
            )

        self._write_behind(write)
        return StoredEvent(run_id, mission_time_s, now, kind, vehicle_id, detail)

    @_after_queued
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
        values = [(run_id, *r) for r in rows]

        def write(db: sqlite3.Connection) -> None:
            db.executemany("INSERT INTO telemetry VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?, ?)", values)

        self._write_behind(write)

    @_after_queued
    def telemetry(self, run_id: int) -> list[TelemetryRow]:
        """A run's rows (as ``add_telemetry`` took them), by mission time."""
        rows = self._db.execute(
            "SELECT mission_time_s, vehicle_id, lat_deg, lon_deg, alt_amsl_m, x_m, y_m, z_m, "
            "speed_m_s FROM telemetry WHERE run_id = ? ORDER BY mission_time_s, vehicle_id",
            (run_id,),
        ).fetchall()
        return [tuple(r) for r in rows]

    @_after_queued
    def telemetry_count(self, run_id: int) -> int:
        row = self._db.execute("SELECT COUNT(*) FROM telemetry WHERE run_id = ?", (run_id,))
        return int(row.fetchone()[0])
