"""The planner pool: one home for the chain robot -> database -> region planner -> stop planner.

A process holds one :class:`PlannerPool` per data folder; the REST service, the command line
and every Dask worker take their planners from it, so the same robot config and database give
the same planner (and its caches) wherever the request came from.

What the pool keeps, and what invalidates it:

- robots, by the content of their config and the folder its paths start from (a hash, never an
  object's identity); a loaded robot never changes, so it is kept while the pool lives;
- reachability databases, by (robot hash, database id); :meth:`PlannerPool.drop_database`
  forgets a deleted database (and every planner over it);
- a :class:`PlannerSlot` per (robot hash, database id): the region planner, the stop planner
  over it (made on first use: it loads the route solver) and the lock that serialises their
  caches, which are not thread-safe;
- which database a robot's plans use when none is named: the one the settings name for it
  (``default_databases``), else the first completed with the default build parameters (see
  :func:`pickstop.store.reach_catalog.default_row`), chosen when first asked (or
  :meth:`PlannerPool.preload`) and kept until that database is dropped.

Forked API workers share one copy of the default database: the parent preloads a pool and the
children inherit it with the process (copy-on-write; nothing writes the arrays).
"""

from __future__ import annotations

import hashlib
import threading
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

from pickstop.caching import Cache
from pickstop.robot.config import (
    RobotConfig,
    RobotConfigError,
    config_from_text,
    load_config,
    resolve_robot,
    robot_config_file,
)
from pickstop.robot.model import RobotModel, load_robot
from pickstop.scene.model import Scene
from pickstop.settings import cache_dir

if TYPE_CHECKING:  # the database (SQLite catalog), the planners and their solvers load on use
    from pickstop.reach.database import ReachDatabase
    from pickstop.speedups.region_planner import RegionPlanner
    from pickstop.speedups.stop_planner import StopPlanner

DEFAULT_ROBOT = "tiago"  # the robot a service preloads


def scene_robot(
    scene: Scene, scene_root: Path | None, configs: ConfigFiles | None = None
) -> tuple[RobotConfig, Path]:
    """The robot config a scene names (a preset, or a config file relative to
    ``scene_root``) and the folder its paths start from; ``configs``: where parsed config
    files are kept (None: parsed now)."""
    ref = scene.robot
    if ref.config is None:
        return resolve_robot(ref.ref) if configs is None else configs.resolve(ref.ref)
    path = Path(ref.config)
    if not path.is_absolute() and scene_root is not None:
        path = scene_root / path
    return load_config(path) if configs is None else configs.load(path)


class ConfigFiles:
    """Robot config files, parsed once per text: a request names its robot every time, and
    parsing a YAML config takes milliseconds. The file is read every time; a text read
    before at the same path is not parsed again (a config is frozen, so the one parsed before
    is the same). The last ``size`` texts are kept."""

    def __init__(self, size: int = 32) -> None:
        self._parsed: Cache[tuple[str, str], tuple[RobotConfig, Path]] = Cache(
            "robot_configs", max_items=size
        )

    def load(self, path: str | Path) -> tuple[RobotConfig, Path]:
        """:func:`load_config`, remembered."""
        path = Path(path)
        if not path.is_file():
            raise RobotConfigError(f"{path}: robot config file not found")
        text = path.read_text(encoding="utf-8")
        key = (str(path.resolve()), hashlib.sha256(text.encode()).hexdigest())
        return self._parsed.get_or_make(key, lambda: config_from_text(path, text))

    def resolve(self, robot: str) -> tuple[RobotConfig, Path]:
        """:func:`resolve_robot`, remembered."""
        return self.load(robot_config_file(robot))


def scene_robot_source(scene: Scene, scene_root: Path | None) -> str:
    """What ``--robot`` takes to name the robot a scene names: the preset, or the config
    file's path (relative to the working folder when it lies inside it, else absolute)."""
    ref = scene.robot
    if ref.config is None:
        return ref.ref
    path = Path(ref.config)
    if not path.is_absolute() and scene_root is not None:
        path = scene_root / path
    path = path.resolve()
    try:
        return str(path.relative_to(Path.cwd().resolve()))
    except ValueError:
        return str(path)


def config_key(config: RobotConfig, root: Path) -> str:
    """The identity of a robot config by value: its content and the folder its paths start
    from (the same text elsewhere names other files)."""
    blob = f"{config.model_dump_json()}\0{Path(root).resolve()}"
    return hashlib.sha256(blob.encode()).hexdigest()


@dataclass
class PlannerSlot:
    """The planners of one robot and database, and the lock their caches need."""

    regions: RegionPlanner
    lock: threading.Lock = field(default_factory=threading.Lock)
    _stops: StopPlanner | None = field(default=None, repr=False)

    @property
    def planner(self) -> StopPlanner:
        """The stop planner over :attr:`regions`, made on first use."""
        if self._stops is None:
            from pickstop.speedups.stop_planner import StopPlanner

            self._stops = StopPlanner(self.regions)
        return self._stops

    def close(self) -> None:
        self.regions.close()


class PlannerPool:
    """Robots, databases and planners of one data folder, each loaded once per process."""

    def __init__(
        self,
        data_dir: Path,
        region_processes: int = 1,
        default_databases: Mapping[str, str] | None = None,
    ) -> None:
        """region_processes: the planners' ``workers`` (processes computing a plan's regions
        at once, :mod:`pickstop.runtime.region_processes`); default_databases: robot name -> the
        database its plans use when they name none (None: the settings')."""
        self.data_dir = Path(data_dir)
        self.region_processes = region_processes
        if default_databases is None:
            from pickstop.settings import Settings

            default_databases = Settings().default_databases
        self.default_databases = dict(default_databases)
        self._robots: dict[str, RobotModel] = {}  # config_key -> robot
        self._databases: dict[tuple[str, str], ReachDatabase] = {}  # (robot hash, db id)
        self._defaults: dict[str, str] = {}  # robot hash -> the database used when none named
        self._slots: dict[tuple[str, str], PlannerSlot] = {}  # (robot hash, db id)
        self._loaded: tuple[PlannerSlot, ...] = ()  # its values, replaced whole under the lock
        self._lock = threading.RLock()
        self.configs = ConfigFiles()  # robot config files, parsed once per text

    # -- the chain ---------------------------------------------------------------------------
    def robot(self, config: RobotConfig, root: Path, source: str = "") -> RobotModel:
        """The robot model of ``config`` (paths from ``root``), built once: parsing the URDF and
        meshes takes about 50 ms, too much for every request. ``source``: what ``--robot``
        takes to name it (a preset or a config path), for the commands errors print."""
        key = config_key(config, root)
        with self._lock:
            robot = self._robots.get(key)
            if robot is None:
                robot = self._robots[key] = load_robot(config, root)
            if source and not robot.source:
                robot.source = source
            return robot

    def database(self, robot: RobotModel, db_id: str | None = None) -> ReachDatabase:
        """The reachability database ``db_id`` of ``robot`` (default: the robot's default)."""
        with self._lock:
            if db_id is None:
                db_id = self._defaults.get(robot.robot_hash)
            db = None if db_id is None else self._databases.get((robot.robot_hash, db_id))
            if db is None:
                from pickstop.store.reach_catalog import open_database

                default = self.default_databases.get(robot.name)
                db = open_database(self.data_dir, robot, db_id, default)
                self._databases[(robot.robot_hash, db.id)] = db
            if db_id is None:
                self._defaults[robot.robot_hash] = db.id
            return db

    def slot(self, robot: RobotModel, db_id: str | None = None) -> PlannerSlot:
        """The planners of ``robot`` over its database ``db_id`` (default: its default)."""
        from pickstop.speedups.region_planner import RegionPlanner

        with self._lock:
            db = self.database(robot, db_id)
            key = (robot.robot_hash, db.id)
            slot = self._slots.get(key)
            if slot is None:
                rp = RegionPlanner(
                    robot, db, cache_dir=cache_dir(self.data_dir), workers=self.region_processes
                )
                slot = self._slots[key] = PlannerSlot(rp)
                self._loaded = tuple(self._slots.values())
            return slot

    def scene_slot(
        self, scene: Scene, scene_root: Path | None, db_id: str | None = None
    ) -> PlannerSlot:
        """The planners of the robot a scene file names (see :func:`scene_robot`)."""
        config, root = scene_robot(scene, scene_root, self.configs)
        robot = self.robot(config, root, scene_robot_source(scene, scene_root))
        return self.slot(robot, db_id)

    def region_planner(
        self, scene: Scene, scene_root: Path | None, db_id: str | None = None
    ) -> RegionPlanner:
        return self.scene_slot(scene, scene_root, db_id).regions

    def stop_planner(
        self, scene: Scene, scene_root: Path | None, db_id: str | None = None
    ) -> StopPlanner:
        return self.scene_slot(scene, scene_root, db_id).planner

    # -- start-up, invalidation, closing -----------------------------------------------------
    def has_database(self, robot: RobotModel) -> bool:
        """Whether the data folder holds a complete database of ``robot``."""
        from pickstop.store.reach_catalog import list_databases

        return any(
            r["robot_hash"] == robot.robot_hash and r["state"] == "complete"
            for r in list_databases(self.data_dir)
        )

    def preload(self, robot_name: str = DEFAULT_ROBOT) -> PlannerSlot | None:
        """Load a preset robot's planners if it has a database (at start-up, and in a parent
        before it forks workers that inherit them); None if it has none."""
        robot = self.robot(*self.configs.resolve(robot_name))
        if not self.has_database(robot):
            return None
        return self.slot(robot)

    def drop_database(self, db_id: str) -> None:
        """Forget the database ``db_id`` and close the planners over it (it was deleted)."""
        with self._lock:
            for key in [k for k in self._databases if k[1] == db_id]:
                del self._databases[key]
            for robot_hash in [h for h, d in self._defaults.items() if d == db_id]:
                del self._defaults[robot_hash]
            gone = [self._slots.pop(k) for k in [k for k in self._slots if k[1] == db_id]]
            self._loaded = tuple(self._slots.values())
            for slot in gone:
                slot.close()

    @property
    def slots(self) -> list[PlannerSlot]:
        """The planners loaded so far, read without the pool's lock: loading a robot or a
        database and closing planners hold it for seconds, and ``/health`` reads this on the
        API's event loop."""
        return list(self._loaded)

    def close(self) -> None:
        """Stop the planners' worker processes; the pool may be used again after."""
        with self._lock:
            for slot in self._slots.values():
                slot.close()
