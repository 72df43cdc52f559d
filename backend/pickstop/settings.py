"""Settings from the environment (prefix ``PICKSTOP_``), e.g. ``PICKSTOP_DATA_DIR``."""

from __future__ import annotations

from pathlib import Path

from pydantic import Field
from pydantic_settings import BaseSettings, SettingsConfigDict

_REPO_DATA = Path(__file__).resolve().parents[2] / "database" / "data"


def _default_data_dir() -> Path:
    # In a checkout the default data folder is database/data (git-ignored); installed
    # elsewhere, the user's data folder.
    if _REPO_DATA.parent.is_dir():
        return _REPO_DATA
    return Path.home() / ".local" / "share" / "pickstop"


class Settings(BaseSettings):
    model_config = SettingsConfigDict(env_prefix="PICKSTOP_", extra="ignore")

    data_dir: Path = Field(default_factory=_default_data_dir, description="where databases live")
    cache_dir: Path | None = Field(
        default=None, description="derived per-robot data (default: <data_dir>/cache)"
    )


def data_dir(override: str | Path | None = None) -> Path:
    """The data folder (created if missing): ``override``, ``$PICKSTOP_DATA_DIR``, or default."""
    path = Path(override) if override is not None else Settings().data_dir
    path.mkdir(parents=True, exist_ok=True)
    return path


def cache_dir(data: Path) -> Path:
    """Where per-robot derived data is cached: ``$PICKSTOP_CACHE_DIR`` or ``<data>/cache``."""
    configured = Settings().cache_dir
    return configured if configured is not None else Path(data) / "cache"
