"""One planner pool: the core keeps no module-level caches, and the service, the command line
and a Dask worker get the same planner for the same robot and database from a pool."""

from __future__ import annotations

import argparse
import ast
import importlib
import json
import pkgutil
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).parents[1]
CORE = ["pickstop.robot", "pickstop.reach", "pickstop.scene", "pickstop.regions",
        "pickstop.sequence", "pickstop.pool"]  # fmt: skip
SCENE = ROOT / "examples" / "scenes" / "paper_experiment.json"

#: Module-level containers that are constant tables (read, never written).
CONSTANT_TABLES = {
    ("pickstop.robot.model", "_KIND_BY_SHORTNAME"),  # URDF joint type -> kind
    ("pickstop.robot.kinematics", "_OTHER_AXES"),  # axis -> the other two
    ("pickstop.robot.selfcollision", "__all__"),
    ("pickstop.regions.solve", "VERSION"),  # the algorithm's parameters, in region keys
}
#: Module names a function rebinds (``global``): the one object a process pool's workers
#: inherit when forked or are handed by their initializer; ``multiprocessing`` calls a
#: module-level function in the worker, which finds its heavy object only there.
PROCESS_POOL_SLOTS = {
    ("pickstop.reach.build", "_WORKER_KERNEL"),  # a build's kernel, set by the initializer
    ("pickstop.runtime.region_processes", "_COMPUTE"),  # the planner's computation, per helper
}
#: Counters of work done, for reports and tests: they hold no results and decide nothing.
COUNTERS = {
    ("pickstop.robot.cache", "COMPUTED"),  # robot-derived entries this process computed
}
#: Caches of pure functions of a file's identity (path, time, size) and constants: what they
#: hold cannot go stale and decides nothing a caller could pass differently.
FILE_KEYED = {
    ("pickstop.scene.supports", "_BOUNDS"),  # a mesh file's bounding box
}
CONTAINER_CALLS = {"dict", "set", "list", "defaultdict", "OrderedDict", "deque", "Counter",
                   "WeakValueDictionary", "WeakKeyDictionary", "ChainMap", "Cache"}  # fmt: skip
CACHE_DECORATORS = {"lru_cache", "cache", "cached"}


def _core_modules() -> dict[str, Path]:
    out = {}
    for name in CORE:
        path = ROOT / "backend" / Path(*name.split("."))
        if path.with_suffix(".py").is_file():
            out[name] = path.with_suffix(".py")
            continue
        for f in path.rglob("*.py"):
            parts = [*name.split("."), *f.relative_to(path).with_suffix("").parts]
            out[".".join(p for p in parts if p != "__init__")] = f
    return out


def _is_container(node: ast.expr | None) -> bool:
    if isinstance(node, ast.Dict | ast.Set | ast.List | ast.DictComp | ast.SetComp | ast.ListComp):
        return True
    if isinstance(node, ast.Call):
        f = node.func
        name = f.id if isinstance(f, ast.Name) else f.attr if isinstance(f, ast.Attribute) else ""
        return name in CONTAINER_CALLS
    return False


def _decorator_name(d: ast.expr) -> str:
    d = d.func if isinstance(d, ast.Call) else d
    return d.id if isinstance(d, ast.Name) else d.attr if isinstance(d, ast.Attribute) else ""


def module_state(module: str, path: Path) -> list[tuple[str, str, str]]:
    """What in ``module`` could hold state across calls: module-level containers, cached
    functions and names rebound by ``global``: ``(module, name, what)``."""
    tree = ast.parse(path.read_text())
    found = []
    for node in tree.body:
        targets: list[ast.expr] = []
        if isinstance(node, ast.Assign):
            targets, value = node.targets, node.value
        elif isinstance(node, ast.AnnAssign):
            targets, value = [node.target], node.value
        if targets and _is_container(value):
            for t in targets:
                if isinstance(t, ast.Name):
                    found.append((module, t.id, "module-level container"))
        if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef | ast.ClassDef):
            for d in node.decorator_list:
                if _decorator_name(d) in CACHE_DECORATORS and isinstance(node, ast.FunctionDef):
                    found.append((module, node.name, "cached function"))
    for node in ast.walk(tree):
        if isinstance(node, ast.Global):
            found += [(module, n, "rebound by global") for n in node.names]
    return found


def test_the_scan_finds_module_caches(tmp_path):
    f = tmp_path / "m.py"
    f.write_text(
        "import functools\nfrom collections import OrderedDict\n_MEMO: dict = {}\n"
        "_LRU = OrderedDict()\n@functools.lru_cache\ndef g(x): return x\n"
        "_SLOT = None\ndef h():\n    global _SLOT\n    _SLOT = 1\n"
        "_KEPT: Cache[str, int] = Cache('kept', max_items=4)\n"
    )
    assert {n for _, n, _ in module_state("m", f)} == {"_MEMO", "_LRU", "g", "_SLOT", "_KEPT"}


def test_no_core_module_holds_a_module_level_cache():
    found = [
        s for m, p in sorted(_core_modules().items()) for s in module_state(m, p)
        if (s[0], s[1]) not in CONSTANT_TABLES | PROCESS_POOL_SLOTS | COUNTERS | FILE_KEYED
    ]  # fmt: skip
    assert found == [], found


def _snapshot() -> dict[tuple[str, str], int]:
    """The size of every module-level container of the loaded core modules."""
    out = {}
    for name in CORE:
        pkg = importlib.import_module(name)
        for m in pkgutil.walk_packages(getattr(pkg, "__path__", []), name + "."):
            importlib.import_module(m.name)
    for name, mod in list(sys.modules.items()):
        if not any(name == c or name.startswith(c + ".") for c in CORE):
            continue
        for attr, value in vars(mod).items():
            if isinstance(value, dict | list | set) and not attr.startswith("__"):
                out[(name, attr)] = len(value)
    return out


@pytest.fixture(scope="module")
def pool(region_db):
    from pickstop.pool import PlannerPool

    folder, _ = region_db
    p = PlannerPool(folder)
    yield p
    p.close()


@pytest.fixture(scope="module")
def service(region_db, pool):
    from pickstop.api.service import Service
    from pickstop.settings import Settings

    folder, _ = region_db
    # Planning on this process's threads (as the planner process itself does), on the given pool.
    svc = Service(Settings(data_dir=folder, planner_processes=0), job_runner=False, planners=pool)
    yield svc
    svc.close()


def test_nothing_at_module_level_grows_when_planning(pool, tmp_path):
    from pickstop.cli.plan import _plan_one
    from pickstop.sequence.plan_model import PlanOptions

    doc = json.loads(SCENE.read_text())
    doc["trays"][0]["pose"]["x"] += 0.013  # a layout no other test planned
    path = tmp_path / "moved.json"
    path.write_text(json.dumps(doc))
    before = _snapshot()
    _plan_one(pool, path, argparse.Namespace(db=None, workers=1), PlanOptions(samples=50))
    after = _snapshot()
    grown = {
        k: (before.get(k, 0), n)
        for k, n in after.items()
        if n != before.get(k, 0) and k not in COUNTERS
    }
    assert grown == {}, grown


def test_service_cli_and_dask_get_one_planner_per_robot_and_database(pool, service, region_db):
    from pickstop.cli.plan import _plan_one
    from pickstop.sequence.plan_model import PlanOptions

    _, db = region_db
    # The service: a request's scene names the preset; the CLI: the same scene from its file.
    scene = service.scenes.parse(json.loads(SCENE.read_text()))
    slot = service.planning.slot(scene)
    assert slot is service.planning.slot(scene, db.id)  # the default database is that one
    plan = _plan_one(pool, SCENE, argparse.Namespace(db=None, workers=1), PlanOptions(samples=0))
    assert plan.database == db.id
    assert pool.slots == [slot]  # the CLI planned on the service's planner, nothing new loaded
    assert pool.region_planner(scene, SCENE.parent) is slot.regions
    assert pool.stop_planner(scene, SCENE.parent, db.id) is slot.planner
    # Another load of the same config is the same robot (by content, not identity).
    from pickstop.robot.config import resolve_robot

    assert pool.robot(*resolve_robot("tiago")) is slot.regions.robot
    assert service.planning.loaded == [{"robot": "tiago", "database": db.id}]


def _worker_slot(data_dir: str) -> tuple[int, int, str, str]:
    from pickstop.distributed import worker_pool
    from pickstop.scene.load import load_scene

    pool = worker_pool(Path(data_dir))
    slot = pool.scene_slot(load_scene(SCENE), SCENE.parent)
    return id(pool), id(slot), slot.regions.robot.robot_hash, slot.regions.db.id


def test_a_dask_worker_keeps_one_pool_and_planner_between_tasks(region_db, pool, service):
    distributed = pytest.importorskip("distributed")
    from pickstop.distributed import PoolPlugin

    folder, db = region_db
    with distributed.LocalCluster(n_workers=1, processes=False, threads_per_worker=1,
                                  dashboard_address=None) as cluster, \
            distributed.Client(cluster) as client:  # fmt: skip
        client.register_plugin(PoolPlugin(), name=PoolPlugin.name)
        first = client.submit(_worker_slot, str(folder), pure=False).result()
        client.register_plugin(PoolPlugin(), name=PoolPlugin.name)  # a second batch: kept
        second = client.submit(_worker_slot, str(folder), pure=False).result()
    assert first == second
    robot = service.planning.slot(service.scenes.parse(json.loads(SCENE.read_text())))
    assert first[2:] == (robot.regions.robot.robot_hash, db.id)  # the service's key


def test_dropping_a_database_closes_its_planners(region_db):
    from pickstop.pool import PlannerPool
    from pickstop.robot.config import resolve_robot

    folder, db = region_db
    p = PlannerPool(folder)
    robot = p.robot(*resolve_robot("tiago"))
    slot = p.slot(robot)
    assert p.slot(robot, db.id) is slot and p.database(robot) is slot.regions.db
    p.drop_database(db.id)
    assert p.slots == []
    again = p.slot(robot)  # opened anew from the data folder
    assert again is not slot and again.regions.db.id == db.id
    p.close()


def test_the_loaded_planners_are_read_while_the_pool_is_busy(region_db):
    """Loading a robot or database and closing planners hold the pool's lock for seconds;
    ``/health`` lists the loaded planners on the API's event loop, so that read never waits."""
    import threading
    import time

    from pickstop.pool import PlannerPool
    from pickstop.robot.config import resolve_robot

    folder, db = region_db
    p = PlannerPool(folder)
    slot = p.slot(p.robot(*resolve_robot("tiago")))
    held, release = threading.Event(), threading.Event()

    def busy() -> None:
        with p._lock:
            held.set()
            release.wait(10)

    threading.Thread(target=busy, daemon=True).start()
    assert held.wait(5)
    t0 = time.perf_counter()
    assert p.slots == [slot]
    assert time.perf_counter() - t0 < 0.5
    release.set()
    p.drop_database(db.id)
    assert p.slots == []
    p.close()


def test_config_files_parse_a_text_once_and_a_changed_text_again(tmp_path):
    from pickstop.errors import RobotConfigError
    from pickstop.pool import ConfigFiles
    from pickstop.robot.config import PRESET_DIR

    path = tmp_path / "bot.yaml"
    text = (PRESET_DIR / "tiago.yaml").read_text()
    path.write_text(text)
    configs = ConfigFiles(size=2)
    first, _ = configs.load(path)
    assert configs.load(path)[0] is first  # the same text: not parsed again
    path.write_text(text.replace("name: tiago", "name: tiago_copy", 1))
    again, _ = configs.load(path)
    assert again is not first and again.name == "tiago_copy"
    with pytest.raises(RobotConfigError):
        configs.load(tmp_path / "nope.yaml")
