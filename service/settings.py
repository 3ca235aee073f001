"""Service configuration from ``DEMSCALE_*`` environment variables (pydantic-settings).

Every field can be set from the environment, e.g. ``DEMSCALE_DATA_DIR=/srv/demscale``,
``DEMSCALE_MAX_PARTICLES_PER_RUN=20000``. The API and the worker must agree on the database
URL and the data directory; the worker also reads its timings from here.
"""

from __future__ import annotations

from functools import lru_cache
from pathlib import Path

from pydantic import Field
from pydantic_settings import BaseSettings, SettingsConfigDict


class Settings(BaseSettings):
    """Configuration of the API and the worker (environment prefix ``DEMSCALE_``)."""

    model_config = SettingsConfigDict(env_prefix="DEMSCALE_", extra="ignore")

    data_dir: Path = Field(Path("var"), description="Result files live under data_dir/studies.")
    database_url: str | None = Field(
        None, description="SQLAlchemy URL; default sqlite:///<data_dir>/demscale.db."
    )

    # admission limits of a study
    max_particles_per_run: int = Field(50_000, gt=0, description="Largest run allowed [-].")
    max_particle_steps: float = Field(
        2e10, gt=0, description="Largest estimated particle-steps of a whole study [-]."
    )
    max_runs: int = Field(64, gt=0, description="Largest number of runs in a study [-].")

    # worker
    heartbeat_interval: float = Field(2.0, gt=0, description="Seconds between heartbeats.")
    stale_after: float = Field(
        30.0, gt=0, description="A running study whose heartbeat is this old [s] is orphaned."
    )
    max_attempts: int = Field(3, ge=1, description="Claims of a study before it is failed.")
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


@lru_cache
def get_settings() -> Settings:
    """The process-wide settings (a FastAPI dependency; override it in tests)."""
    return Settings()
