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
        default=None,
        description="derived per-robot data (self-collision pairs and screen, hulls, outline), "
        "one cache for every data folder and process (default: $XDG_CACHE_HOME/pickstop or "
        "~/.cache/pickstop)",
    )
    # -- the REST service -----------------------------------------------------------------
    host: str = Field(default="127.0.0.1", description="address the API listens on")
    port: int = Field(default=8000, ge=1, le=65535, description="API port")
    ui_port: int = Field(default=8080, ge=1, le=65535, description="3D planner port")
    mqtt_broker: str | None = Field(
        default=None,
        description="MQTT broker the API dispatches orders to (mqtt://HOST:PORT); unset: "
        "dispatch is refused",
    )
    vehicle_types: Path | None = Field(
        default=None,
        description="vehicle types file (pickstop.vehicles): the pick action and parameter "
        "names of each vehicle type, for exports and dispatches",
    )
    api_keys: list[str] = Field(
        default_factory=list,
        description="accepted API keys, stored hashed as 'sha256:<hex>' (pickstop api-key makes "
        "one); empty: writes are refused",
    )
    read_requires_key: bool = Field(default=False, description="require a key for reads too")
    default_databases: dict[str, str] = Field(
        default_factory=dict,
        description="robot name -> the reachability database its plans use when they name "
        "none (JSON); a robot not listed uses the first database completed for it with the "
        "default build parameters (else the first completed)",
    )
    max_body_bytes: int = Field(default=2_000_000, ge=1024, description="request body limit")
    max_yaml_bytes: int = Field(
        default=100_000, ge=1024, description="YAML request body limit (robot configs) [bytes]"
    )
    max_grid_cells: int = Field(default=250_000, ge=1, description="base grid cells per scene")
    max_samples: int = Field(default=50_000_000, ge=1, description="samples per database build")
    max_batch: int = Field(default=200, ge=1, description="scenes per batch job")
    max_orders: int = Field(default=200, ge=1, description="orders of a mix per request")
    max_trays: int = Field(default=40, ge=1, description="trays per scene")
    max_parts_per_tray: int = Field(default=50, ge=1, description="parts per tray")
    max_parts: int = Field(default=300, ge=1, description="parts per scene, all trays")
    max_obstacles: int = Field(default=200, ge=0, description="obstacles per scene")
    max_mesh_triangles: int = Field(
        default=200_000, ge=0, description="triangles of every mesh of a scene together"
    )
    max_mc_samples: int = Field(
        default=20_000, ge=0, description="Monte Carlo samples per stop of a plan"
    )
    request_deadline: float = Field(
        default=60.0, gt=0, description="seconds a synchronous request may compute (then 504)"
    )
    workers: int = Field(
        default=1, ge=1, le=32, description="API processes sharing the port (pickstop serve)"
    )
    planner_processes: int = Field(
        default=1,
        ge=0,
        le=1,
        description="child processes that compute plans, previews and regions, so that reads "
        "never wait on a planner for the interpreter lock (0: threads of the API process)",
    )
    region_processes: int = Field(
        default=2,
        ge=1,
        le=32,
        description="processes computing a plan's regions at once: the planner's own and "
        "helpers forked from it, each tray computed where it was before (1: the planner alone)",
    )
    job_deadline: float = Field(
        default=6 * 3600.0, gt=0, description="seconds a job may run (then it fails)"
    )
    interrupted_retention: float = Field(
        default=24 * 3600.0,
        ge=0,
        description="seconds after its start a database whose build was interrupted is kept "
        "(resumable by the same build) before it is deleted; a cancelled build is deleted at once",
    )


def hash_key(key: str) -> str:
    """How an API key is stored: ``sha256:<hex>`` of the key."""
    import hashlib

    return "sha256:" + hashlib.sha256(key.encode()).hexdigest()


def data_dir(override: str | Path | None = None) -> Path:
    """The data folder (created if missing): ``override``, ``$PICKSTOP_DATA_DIR``, or default."""
    path = Path(override) if override is not None else Settings().data_dir
    path.mkdir(parents=True, exist_ok=True)
    return path


def user_cache_dir() -> Path:
    """The user's cache folder for PickStop: ``$XDG_CACHE_HOME/pickstop`` or
    ``~/.cache/pickstop``."""
    import os

    xdg = os.environ.get("XDG_CACHE_HOME")
    return (Path(xdg) if xdg else Path.home() / ".cache") / "pickstop"


def cache_dir(data: Path | None = None) -> Path:
    """Where per-robot derived data is cached: ``$PICKSTOP_CACHE_DIR``, else the user's cache
    folder (:func:`user_cache_dir`). One cache serves every data folder (``data`` does not
    change it): a robot's derived data depends on the robot alone, keyed by its hash."""
    configured = Settings().cache_dir
    return configured if configured is not None else user_cache_dir()
