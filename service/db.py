"""The SQLite job store: engine (WAL mode, busy timeout), table creation and sessions.

SQLite serialises writers; WAL lets readers (the API) proceed while a worker writes. Status
changes are single conditional UPDATEs (see :mod:`service.transitions`), so every write
transaction starts with its write and waits on the busy timeout instead of failing.
"""

from __future__ import annotations

from collections.abc import Iterator
from functools import lru_cache
from pathlib import Path

from sqlalchemy import Engine, event, inspect, text
from sqlalchemy.engine import make_url
from sqlalchemy.exc import OperationalError
from sqlmodel import Session, SQLModel, create_engine

from . import models  # noqa: F401  (registers the tables on SQLModel.metadata)
from .settings import Settings

#: Seconds a connection waits for the write lock before giving up.
BUSY_TIMEOUT_S = 30.0


def _sqlite_pragmas(dbapi_connection, _record) -> None:
    cur = dbapi_connection.cursor()
    cur.execute("PRAGMA journal_mode=WAL")
    cur.execute("PRAGMA synchronous=NORMAL")
    cur.execute(f"PRAGMA busy_timeout={int(BUSY_TIMEOUT_S * 1000)}")
    cur.execute("PRAGMA foreign_keys=ON")
    cur.close()


@lru_cache(maxsize=16)
def get_engine(url: str) -> Engine:
    """The SQLAlchemy engine of ``url``, tables created (one per URL and process)."""
    u = make_url(url)
    kwargs: dict = {}
    if u.get_backend_name() == "sqlite":
        if u.database and u.database != ":memory:":
            Path(u.database).parent.mkdir(parents=True, exist_ok=True)
        kwargs["connect_args"] = {"check_same_thread": False, "timeout": BUSY_TIMEOUT_S}
    engine = create_engine(url, **kwargs)
    if u.get_backend_name() == "sqlite":
        event.listen(engine, "connect", _sqlite_pragmas)
    try:
        SQLModel.metadata.create_all(engine)
    except OperationalError:  # another process created the tables at the same moment
        SQLModel.metadata.create_all(engine)
    # a store made before studies had owners: its old studies belong to no token (owner ''),
    # so no token can read them through the API
    _add_column(
        engine,
        "owner",
        "ALTER TABLE study ADD COLUMN owner VARCHAR(16) NOT NULL DEFAULT ''",
        "CREATE INDEX IF NOT EXISTS ix_study_owner ON study (owner)",
    )
    # a store made before studies kept their plan: NULL, such a study's worker plans it
    # from its spec
    _add_column(engine, "plan", "ALTER TABLE study ADD COLUMN plan JSON")
    # a store made before calibrations: every job in it is a study
    _add_column(
        engine,
        "kind",
        "ALTER TABLE study ADD COLUMN kind VARCHAR(11) NOT NULL DEFAULT 'study'",
        "CREATE INDEX IF NOT EXISTS ix_study_kind ON study (kind)",
    )
    # a store made before the worker wrote its expected end: unknown until the next beat
    _add_column(engine, "finishes_at", "ALTER TABLE study ADD COLUMN finishes_at DATETIME")
    _add_column(
        engine,
        "parent_id",
        "ALTER TABLE study ADD COLUMN parent_id CHAR(32)",
        "CREATE INDEX IF NOT EXISTS ix_study_parent_id ON study (parent_id)",
    )
    return engine


def _add_column(engine: Engine, name: str, *ddl: str) -> None:
    """Add column ``name`` to the study table of a store made before it existed (``ddl``:
    the statements that add it); nothing if it is there. Two processes starting on one
    store may both try: the second one's error is the column already being there."""
    if name in {c["name"] for c in inspect(engine).get_columns("study")}:
        return
    try:
        with engine.begin() as conn:
            for statement in ddl:
                conn.execute(text(statement))
    except OperationalError:  # another process added it at the same moment
        pass


def engine_for(settings: Settings) -> Engine:
    """The engine of the configured database."""
    return get_engine(settings.sqlalchemy_url)


def session_scope(settings: Settings) -> Iterator[Session]:
    """A session on the configured database, closed afterwards (a FastAPI dependency body)."""
    with Session(engine_for(settings)) as session:
        yield session
