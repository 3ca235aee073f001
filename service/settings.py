"""Service configuration from ``DEMSCALE_*`` environment variables (pydantic-settings).

Every field can be set from the environment, e.g. ``DEMSCALE_DATA_DIR=/srv/demscale``,
``DEMSCALE_MAX_PARTICLES_PER_RUN=20000``. The API and the worker must agree on the database
URL and the data directory; the worker also reads its timings from here.
"""

from __future__ import annotations

import hashlib
import ipaddress
import logging
import os
import secrets
import stat
from functools import lru_cache
from pathlib import Path
from typing import Literal

from pydantic import Field, SecretStr
from pydantic_settings import BaseSettings, SettingsConfigDict

#: Shortest token accepted (characters): a guessable token is no protection.
MIN_TOKEN_LENGTH = 16
#: Hex digits of SHA-256 kept as a token's fingerprint on the rows it owns.
FINGERPRINT_DIGITS = 16


log = logging.getLogger("demscale.settings")


class ConfigError(ValueError):
    """A setting that the service refuses to start with (e.g. no API token)."""


def fingerprint(token: str) -> str:
    """What a study row stores of the token that submitted it: the first 16 hex digits of
    its SHA-256 (never the token itself)."""
    return hashlib.sha256(token.encode()).hexdigest()[:FINGERPRINT_DIGITS]


class Settings(BaseSettings):
    """Configuration of the API and the worker (environment prefix ``DEMSCALE_``)."""

    model_config = SettingsConfigDict(
        env_prefix="DEMSCALE_", extra="ignore", validate_assignment=True
    )

    data_dir: Path = Field(Path("var"), description="Result files live under data_dir/studies.")
    database_url: str | None = Field(
        None, description="SQLAlchemy URL; default sqlite:///<data_dir>/demscale.db."
    )

    # admission limits of a study
    max_particles_per_run: int = Field(50_000, gt=0, description="Largest run allowed [-].")
    max_particle_steps: float = Field(
        2e11, gt=0, description="Largest worst-case particle-steps of a whole study [-]."
    )
    max_calibration_particle_steps: float = Field(
        3e11,
        gt=0,
        description="Largest worst-case particle-steps of a whole calibration (each of its "
        "runs counted as its branches' worst cases) [-].",
    )
    max_runs: int = Field(
        64,
        gt=0,
        description="Largest number of runs in a study, or of parameter sets in a calibration [-].",
    )
    max_curve_samples: int = Field(
        1_000_000,
        gt=0,
        description="Most curve samples a study may store, at the worst "
        "case its bounds allow (stage time caps / output_interval, summed over stages and "
        "runs) [-]; each is 11 float64 values.",
    )
    max_run_wall_time: float = Field(
        21_600.0,
        gt=0,
        description="Wall time [s] after which a run fails (the study goes "
        "on with the other runs), in the worker's process, on a pool or on a Dask cluster "
        "alike; a resumed run counts its earlier attempts up to its checkpoint.",
    )
    submit_rate: float = Field(
        30.0,
        gt=0,
        description="Submissions (and refused requests) a token may make per "
        "minute, in bursts of up to submit_burst; beyond: 429 with Retry-After.",
    )
    submit_burst: int = Field(10, ge=1, description="Largest burst of submissions of a token.")
    auth_failure_rate: float = Field(
        10.0,
        gt=0,
        description="Requests with a wrong token (bearer header or login form) "
        "one client address may make per minute, in bursts of up to auth_failure_burst; "
        "beyond: 429 with Retry-After, until the bucket refills (a right token always "
        "passes).",
    )
    auth_failure_burst: int = Field(
        20, ge=1, description="Largest burst of wrong tokens from one client address."
    )
    max_storage_per_token: float = Field(
        20e9,
        gt=0,
        description="Bytes one token's studies may take on disk: what its studies "
        "hold plus the worst-case size of a new one; beyond: 507.",
    )

    # worker
    heartbeat_interval: float = Field(2.0, gt=0, description="Seconds between heartbeats.")
    stale_after: float = Field(
        30.0, gt=0, description="A running study whose heartbeat is this old [s] is orphaned."
    )
    max_attempts: int = Field(
        3,
        ge=1,
        description="Claims of a study in a row that finish no run and advance no "
        "checkpoint before it is failed (its interrupted run, brought down at the same point "
        "each time, is a poison run); a claim that finishes a run or writes a newer "
        "checkpoint resets the count.",
    )
    checkpoint_interval: float = Field(
        60.0,
        gt=0,
        le=3600,
        description="Wall time [s] between two checkpoints of a run in "
        "flight (engine.Checkpoint): a killed worker's run resumes from its last one, "
        "bit-identically, losing at most this much work.",
    )
    checkpoint_interval_after_crash: float = Field(
        2.0,
        gt=0,
        le=3600,
        description="Wall time [s] between two checkpoints of the runs of a study whose "
        "worker has died once (its heartbeat went stale): a worker killed every few seconds "
        "then still moves the study on, where the default interval would lose every "
        "attempt's work and fail the study by the poison rule; a write of the paper-scale "
        "reference's state takes 0.03 to a few tenths of a second.",
    )
    run_workers: int = Field(
        1,
        ge=0,
        le=256,
        description="Runs of a study side by side on a local process pool, "
        "one engine thread each; 1: one run at a time in the worker with the engine's own "
        "threads; 0: one per core. On the cuda backend the runs are threads of the worker "
        "sharing the GPU, a CUDA stream each.",
    )
    backend: Literal["cpu", "cuda", "auto"] = Field(
        "cpu",
        description="Where the engine runs a study's runs: cpu, cuda (an NVIDIA GPU "
        "with numba-cuda, the gpu extra) or auto (the GPU when usable, else the CPU).",
    )
    dask_scheduler: str | None = Field(
        None,
        max_length=500,
        description="Address of a Dask scheduler (e.g. "
        "tcp://10.0.0.5:8786): runs become tasks on its cluster (needs `distributed`).",
    )
    poll_interval: float = Field(1.0, gt=0, description="Seconds between queue polls.")
    shutdown_grace: float = Field(
        20.0,
        gt=0,
        description="After SIGTERM, seconds to wait for the engine to stop before "
        "the study is requeued and the worker exits anyway.",
    )

    # API
    embedded_worker: bool = Field(
        True, description="The API starts one worker subprocess (single-machine default)."
    )
    worker_log: str | None = Field(
        None,
        description="Where the embedded worker's log goes: a file (appended), '-' for the "
        "API's own output; default <data_dir>/logs/worker.log (a progress display on the "
        "terminal is not interleaved with it).",
    )
    host: str = Field("127.0.0.1", description="Address `python -m service api` listens on.")
    port: int = Field(8000, ge=1, le=65535, description="Its port.")
    api_token: SecretStr | None = Field(
        None, description="The bearer token clients must send (one token)."
    )
    api_token_file: Path | None = Field(
        None,
        description="A file of bearer tokens, one per line ('#' comments and blank lines "
        "ignored); each token sees only the studies it submitted.",
    )
    session_max_age: int = Field(
        8 * 3600,
        ge=60,
        le=30 * 86400,
        description="Seconds a browser's login lasts (the pages' signed session cookie): "
        "after it, log in again.",
    )
    session_secret: SecretStr | None = Field(
        None,
        description="The key that signs the pages' session cookie (32 characters or more); "
        "unset: a random one kept in <data dir>/session-secret (made on first start, 0600).",
    )
    max_active: int = Field(
        100, ge=1, description="Most queued or running studies in all; more answer 429."
    )
    max_active_per_token: int = Field(
        20, ge=1, description="Most queued or running studies of one token; more answer 429."
    )
    retry_after: int = Field(
        60, ge=1, description="Seconds a client is told to wait after a 429 (Retry-After)."
    )
    max_body_bytes: int = Field(
        64 * 1024, ge=1024, description="Largest request body [bytes]; larger answer 413."
    )

    def tokens(self) -> tuple[str, ...]:
        """Every accepted token (``api_token`` and the lines of ``api_token_file``); raises
        :class:`ConfigError` for an unreadable file or a token shorter than 16 characters."""
        out = []
        if self.api_token is not None:
            out.append(self.api_token.get_secret_value().strip())
        if self.api_token_file is not None:
            check_token_file(self.api_token_file)
            try:
                text = self.api_token_file.read_text()
            except OSError as e:
                raise ConfigError(
                    f"DEMSCALE_API_TOKEN_FILE: cannot read {e.filename}: {e.strerror}"
                ) from e
            lines = (line.strip() for line in text.splitlines())
            out += [line for line in lines if line and not line.startswith("#")]
        short = [t for t in out if len(t) < MIN_TOKEN_LENGTH]
        if short:
            raise ConfigError(
                f"{len(short)} API token(s) shorter than {MIN_TOKEN_LENGTH} "
                "characters: use e.g. `python -c 'import secrets; "
                "print(secrets.token_urlsafe(32))'`"
            )
        return tuple(dict.fromkeys(out))

    @property
    def worker_log_path(self) -> Path | None:
        """The embedded worker's log file (None: the API's own output)."""
        if self.worker_log == "-":
            return None
        return Path(self.worker_log) if self.worker_log else self.data_dir / "logs" / "worker.log"

    @property
    def studies_dir(self) -> Path:
        """Directory of the per-study result directories."""
        return self.data_dir / "studies"

    @property
    def sqlalchemy_url(self) -> str:
        """The database URL, defaulting to a SQLite file in the data directory."""
        return self.database_url or f"sqlite:///{self.data_dir / 'demscale.db'}"

    def study_dir(self, study_id: object) -> Path:
        """Directory of one study's files."""
        return self.studies_dir / str(study_id)

    def results_path(self, study_id: object) -> Path:
        """The HDF5 file of one study."""
        return self.study_dir(study_id) / "results.h5"

    def calibration_path(self, study_id: object) -> Path:
        """The result of one calibration (engine.Calibration.to_summary() as JSON)."""
        return self.study_dir(study_id) / "calibration.json"

    def snapshots_dir(self, study_id: object) -> Path:
        """ParaView snapshots and PNG sections of one study's runs, one folder per run."""
        return self.study_dir(study_id) / "snapshots"

    def snapshot_files(self, study_id: object) -> dict[str, list[str]]:
        """Run key -> names of its snapshot files (complete folders only): the files there
        and the ``<stage>.png`` sections its ``sections.npz`` can draw when asked for."""
        from engine.io.vtkhdf import SECTION_DATA, section_stages

        root = self.snapshots_dir(study_id)
        if not root.is_dir():
            return {}
        out = {}
        for d in sorted(root.iterdir()):
            if not d.is_dir() or d.name.startswith("."):
                continue
            names = {f.name for f in d.iterdir() if f.is_file() and not f.name.startswith(".")}
            if SECTION_DATA in names:
                names.discard(SECTION_DATA)
                names.update(f"{stage}.png" for stage in section_stages(d))
            out[d.name] = sorted(names)
        return out

    def checkpoints_dir(self, study_id: object) -> Path:
        """Checkpoints of one study's runs in flight (``<key>.ckpt``), removed once stored."""
        return self.study_dir(study_id) / "checkpoints"

    def crash_log(self, study_id: object) -> Path:
        """Where the worker notes each death of a study's worker (a line per crash)."""
        return self.study_dir(study_id) / "crashes"

    def checkpoint_interval_for(self, study_id: object) -> float:
        """The checkpoint interval of a study's runs: ``checkpoint_interval``, or the
        shorter ``checkpoint_interval_after_crash`` once its worker has died."""
        if self.crash_log(study_id).is_file():
            return min(self.checkpoint_interval, self.checkpoint_interval_after_crash)
        return self.checkpoint_interval

    def run_options(self, study_id: object, executor=None, channel=None):
        """How the worker runs one study's runs (engine.RunOptions): on ``executor`` with
        ``channel``, checkpoints in :meth:`checkpoints_dir` every ``checkpoint_interval``
        (``checkpoint_interval_after_crash`` once a worker of the study has died), the
        per-run wall-time limit (enforced in this process, on a pool or on a cluster alike:
        engine.WallTimeExceeded names DEMSCALE_MAX_RUN_WALL_TIME) and the backend."""
        import engine

        return engine.RunOptions(
            executor=executor,
            channel=channel,
            checkpoints=self.checkpoints_dir(study_id),
            checkpoint_interval=self.checkpoint_interval_for(study_id),
            max_run_wall_time=self.max_run_wall_time,
            wall_time_setting="DEMSCALE_MAX_RUN_WALL_TIME",
            backend=self.backend,
        )

    def runs_dir(self, study_id: object) -> Path:
        """The per-run HDF5 files of one study, each stored as soon as its run ends."""
        return self.study_dir(study_id) / "runs"


def check_token_file(path: Path) -> None:
    """Refuse a token file that every user of the machine can read or write (raises
    :class:`ConfigError` naming the fix); warn about one the file's group can read."""
    try:
        mode = os.stat(path).st_mode
    except OSError:
        return  # the read that follows names the error
    if mode & (stat.S_IROTH | stat.S_IWOTH):
        raise ConfigError(
            f"DEMSCALE_API_TOKEN_FILE: {path} can be read or written by every "
            f"user of this machine (mode {stat.filemode(mode)}): "
            f"`chmod 600 {path}`"
        )
    if mode & (stat.S_IRGRP | stat.S_IWGRP):
        log.warning(
            "DEMSCALE_API_TOKEN_FILE: %s can be read by its group (mode %s); "
            "`chmod 600` keeps the tokens to their owner",
            path,
            stat.filemode(mode),
        )


def secure_data_dir(settings: Settings) -> None:
    """Keep the store to the service's own user: files made from now on by this process
    (and the workers it starts) are 0600 and directories 0700 (umask 077); the data
    directory, the studies directory and a SQLite database already there are narrowed to
    those modes. Called by the API and the worker as they start."""
    os.umask(0o077)
    paths = [(settings.data_dir, 0o700), (settings.studies_dir, 0o700)]
    settings.studies_dir.mkdir(parents=True, exist_ok=True)
    url = settings.sqlalchemy_url
    if url.startswith("sqlite:///"):
        db = Path(url.removeprefix("sqlite:///"))
        paths += [
            (f, 0o600)
            for f in (db, db.with_name(db.name + "-wal"), db.with_name(db.name + "-shm"))
            if f.is_file()
        ]
    for path, mode in paths:
        try:
            if stat.S_IMODE(path.stat().st_mode) & 0o077:
                path.chmod(mode)
        except OSError as e:  # another user's directory (a shared volume): say so, go on
            log.warning("cannot narrow %s to mode %o: %s", path, mode, e.strerror)


def is_loopback(host: str) -> bool:
    """Whether ``host`` is reachable from this machine only."""
    if host == "localhost":
        return True
    try:
        return ipaddress.ip_address(host).is_loopback
    except ValueError:
        return False


#: Name of the token file a loopback-only server makes in its data directory.
LOCAL_TOKEN_FILE = "api-token"


def with_local_token(settings: Settings, host: str) -> tuple[Settings, str | None]:
    """Settings that name a token, for a server on ``host``. Configured tokens are kept
    (returns ``(settings, None)``). Without any, a loopback-only server uses the token in
    ``<data_dir>/api-token``, made on first use (mode 0600), and returns it so that it can
    be shown; any other address raises :class:`ConfigError`."""
    if settings.tokens():
        return settings, None
    if not is_loopback(host):
        raise ConfigError(
            f"refusing to listen on {host} without an API token: set DEMSCALE_API_TOKEN or "
            "DEMSCALE_API_TOKEN_FILE (or listen on 127.0.0.1)"
        )
    path = settings.data_dir / LOCAL_TOKEN_FILE
    path.parent.mkdir(parents=True, exist_ok=True)
    try:
        fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600)
    except FileExistsError:
        pass
    else:
        with os.fdopen(fd, "w") as f:
            f.write(secrets.token_urlsafe(32) + "\n")
    local = settings.model_copy(update={"api_token_file": path.resolve()})
    return local, local.tokens()[0]


#: Where the pages' session-signing key is kept when none is configured.
SESSION_SECRET_FILE = "session-secret"


def session_secret(settings: Settings) -> str:
    """The key that signs the pages' session cookie: ``DEMSCALE_SESSION_SECRET``, or a
    random one kept in ``<data_dir>/session-secret`` (made on first use, mode 0600), so that
    every API process on one data directory signs alike and a restart keeps the logins.
    Raises :class:`ConfigError` for a configured key under 32 characters."""
    if settings.session_secret is not None:
        key = settings.session_secret.get_secret_value()
        if len(key) < 32:
            raise ConfigError("DEMSCALE_SESSION_SECRET must be 32 characters or more")
        return key
    path = settings.data_dir / SESSION_SECRET_FILE
    if not path.exists():  # written whole, then linked into place: no reader sees it empty
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp = path.with_name(f".{SESSION_SECRET_FILE}.{os.getpid()}.tmp")
        fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o600)
        with os.fdopen(fd, "w") as f:
            f.write(secrets.token_urlsafe(48) + "\n")
        try:
            os.link(tmp, path)
        except FileExistsError:  # another process made it first: theirs is the key
            pass
        finally:
            tmp.unlink(missing_ok=True)
    return path.read_text().strip()


@lru_cache
def get_settings() -> Settings:
    """The process-wide settings (a FastAPI dependency; override it in tests)."""
    return Settings()
