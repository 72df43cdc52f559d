"""Scale-out on Dask (distributed): database builds, batch planning and layout search.

``--dask tcp://host:8786`` uses a running scheduler, ``--dask local`` starts a local cluster
(2 worker processes, one thread each). Workers must see the same data folder (a shared volume).

- Build: each sample chunk is a task; the worker writes its shard atomically (temporary file,
  then rename) and returns its checksum; only the client records shards in the catalog, after a
  task's result has arrived, so the catalog never names an incomplete shard. A worker that dies
  loses only its running chunks: Dask reruns them (``retries``), and chunks are deterministic, so
  the rerun writes the same bytes.
- Layout search: one task per candidate layout (every order planned), ranked on the
  worker's planner or verified on a from-scratch one it keeps (:class:`DaskEvaluator`).
- Batch: one task per scene, keyed by the scene's position; each worker process keeps a
  planner pool (robot, database, planners and their caches) between tasks
  (:class:`PoolPlugin`). Results are gathered by key, so a task rerun after a worker died
  still yields its plan once.
"""

from __future__ import annotations

import json
from collections.abc import Iterator
from pathlib import Path
from typing import TYPE_CHECKING, Any

from pickstop.errors import InputError, PickStopError
from pickstop.pool import PlannerPool
from pickstop.reach.build import BuildKernel, ChunkResult, ChunkRunner, compute_chunk

if TYPE_CHECKING:
    from distributed import WorkerPlugin
else:
    try:
        from distributed import WorkerPlugin
    except ImportError:  # Dask is optional: the plugin is only registered when it is there
        WorkerPlugin = object

RETRIES = 3


def client_for(address: str) -> Any:
    """A Dask client: ``local`` (a new local cluster of 2 processes) or a scheduler address."""
    try:
        from distributed import Client, LocalCluster
    except ImportError:
        raise InputError(
            "--dask needs Dask: pip install 'dask[distributed]' (or the [dask] extra)",
            field="dask",
        ) from None
    if address == "local":
        cluster = LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                               dashboard_address=None)  # fmt: skip
        return Client(cluster)
    if not address.startswith(("tcp://", "tls://", "inproc://")):
        raise InputError(f"--dask {address!r}: give 'local' or a scheduler address "
                         "like tcp://host:8786", field="dask")  # fmt: skip
    try:
        return Client(address, timeout=30)
    except OSError as e:
        raise PickStopError(f"--dask {address}: cannot reach the scheduler: {e}") from None


def _chunk_task(kernel: BuildKernel, chunk: int, data_dir: str, db_id: str) -> ChunkResult:
    import os

    os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
    return compute_chunk(kernel, chunk, Path(data_dir), db_id)


def dask_runner(client: Any) -> ChunkRunner:
    """A build runner that computes chunks as Dask tasks and yields results as they finish."""
    from distributed import as_completed

    def run(
        kernel: BuildKernel, chunks: list[int], data_dir: Path, db_id: str
    ) -> Iterator[ChunkResult]:
        if not chunks:
            return
        [kf] = client.scatter([kernel], broadcast=True)
        futures = [
            client.submit(_chunk_task, kf, c, str(data_dir), db_id, key=f"chunk-{db_id}-{c}",
                          retries=RETRIES, pure=False)
            for c in chunks
        ]  # fmt: skip
        try:
            for fut in as_completed(futures):
                yield fut.result()
        finally:
            client.cancel(futures)

    return run


# -- batch planning ------------------------------------------------------------------------
class PoolPlugin(WorkerPlugin):
    """A Dask worker plugin that gives each worker process its planner pools (one per data
    folder), kept between tasks: a worker loads a robot's database and planners once.
    Registered idempotently, so a second batch on the same cluster finds the pools warm."""

    name = "pickstop-planner-pool"
    idempotent = True

    def __init__(self) -> None:
        self.pools: dict[str, PlannerPool] = {}
        self._lock: Any = None  # made on the worker (a lock does not pickle)

    def setup(self, worker: Any) -> None:
        import threading

        self.pools = {}
        self._lock = threading.Lock()  # a worker may run several tasks at once

    def teardown(self, worker: Any) -> None:
        for pool in self.pools.values():
            pool.close()

    def pool(self, data_dir: Path) -> PlannerPool:
        key = str(Path(data_dir).resolve())
        with self._lock:
            pool = self.pools.get(key)
            if pool is None:
                pool = self.pools[key] = PlannerPool(Path(key))
            return pool


def worker_pool(data_dir: Path) -> PlannerPool:
    """The planner pool of this Dask worker process for ``data_dir`` (a pool of its own when
    called outside a worker, or on a worker without the plugin)."""
    try:
        from distributed import get_worker

        plugin = get_worker().plugins.get(PoolPlugin.name)
    except (ImportError, ValueError):  # not in a Dask worker
        plugin = None
    if isinstance(plugin, PoolPlugin):
        return plugin.pool(data_dir)
    return PlannerPool(data_dir)


def plan_task(
    doc: dict[str, Any], options: dict[str, Any], root: str, data_dir: str, db_id: str | None
) -> dict[str, Any]:
    """Plan one scene; a plan document or ``{"error": ..., "exit_code": ...}``."""
    import os

    os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
    from pickstop.scene.load import parse_scene
    from pickstop.scene.model import resolve_mesh_paths
    from pickstop.sequence.plan_model import PlanOptions

    try:
        scene = parse_scene(resolve_mesh_paths(doc, Path(root), source=root), root)
        slot = worker_pool(Path(data_dir)).scene_slot(scene, Path(root), db_id)
        with slot.lock:
            return slot.planner.plan(scene, PlanOptions(**options)).model_dump(mode="json")
    except PickStopError as e:
        return {"error": e.message, "exit_code": e.exit_code}


def plan_batch(
    client: Any,
    items: list[tuple[str, dict[str, Any], Path]],
    options: dict[str, Any],
    data_dir: Path,
    db_id: str | None,
) -> Iterator[tuple[int, dict[str, Any]]]:
    """Plan ``items`` (name, scene document, folder its paths start from) on the cluster;
    yields ``(index, result)`` once per item, in completion order."""
    from distributed import as_completed

    client.register_plugin(PoolPlugin(), name=PoolPlugin.name)
    futures = {
        client.submit(plan_task, doc, options, str(root), str(data_dir), db_id,
                      key=f"plan-{k}-{name}-{_digest(doc)}", retries=RETRIES, pure=False): k
        for k, (name, doc, root) in enumerate(items)
    }  # fmt: skip
    seen: set[int] = set()
    for fut in as_completed(list(futures)):
        k = futures[fut]
        if k in seen:  # a rerun's duplicate result: each scene is reported once
            continue
        seen.add(k)
        yield k, fut.result()


def _digest(doc: dict[str, Any]) -> str:
    import hashlib

    return hashlib.sha256(json.dumps(doc, sort_keys=True).encode()).hexdigest()[:12]


# -- layout search ----------------------------------------------------------------------------
_SCRATCH: dict[str, Any] = {}  # this worker's from-scratch stop planners, by data folder and db


def layout_task(
    doc: dict[str, Any],
    orders: list[dict[str, Any]],
    options: dict[str, Any],
    root: str,
    data_dir: str,
    db_id: str | None,
    verify: bool,
) -> Any:
    """Every order of one candidate layout planned (:class:`~pickstop.sequence.mix.MixPlans`):
    without Monte Carlo on the worker's planner to rank it, or with the options on a planner
    of its own that computes regions from scratch to verify it."""
    import os

    os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
    from pickstop.layout.verify import scratch_planner
    from pickstop.scene.load import parse_scene
    from pickstop.scene.model import Order, resolve_mesh_paths
    from pickstop.sequence.mix import plan_mix
    from pickstop.sequence.plan_model import PlanOptions

    scene = parse_scene(resolve_mesh_paths(doc, Path(root), source=root), root)
    slot = worker_pool(Path(data_dir)).scene_slot(scene, Path(root), db_id)
    opts = PlanOptions(**options)
    with slot.lock:
        if verify:
            key = f"{data_dir}|{slot.regions.db.id}|{slot.regions.robot.robot_hash}"
            if key not in _SCRATCH:
                _SCRATCH[key] = scratch_planner(slot.regions)
            sp = _SCRATCH[key]
        else:
            sp, opts = slot.planner, opts.model_copy(update={"samples": 0})
        return plan_mix(sp, scene, [Order(**o) for o in orders], opts)


class DaskEvaluator:
    """:class:`~pickstop.layout.verify.Evaluator` on a Dask cluster: one task per layout."""

    def __init__(
        self, client: Any, root: Path, data_dir: Path, db_id: str | None, orders: list[Any],
        options: Any,
    ) -> None:  # fmt: skip
        self.client, self.root, self.data_dir, self.db_id = client, root, data_dir, db_id
        self.orders = [o.model_dump() for o in orders]
        self.options = options.model_dump()
        client.register_plugin(PoolPlugin(), name=PoolPlugin.name)

    def _run(self, scenes: list[Any], verify: bool) -> list[Any]:
        docs = [json.loads(s.model_dump_json()) for s in scenes]
        futures = [
            self.client.submit(layout_task, doc, self.orders, self.options, str(self.root),
                               str(self.data_dir), self.db_id, verify, retries=RETRIES,
                               key=f"layout-{int(verify)}-{k}-{_digest(doc)}", pure=False)
            for k, doc in enumerate(docs)
        ]  # fmt: skip
        return [f.result() for f in futures]

    def rank(self, scenes: list[Any]) -> list[Any]:
        return self._run(scenes, verify=False)

    def verify(self, scenes: list[Any]) -> list[Any]:
        return self._run(scenes, verify=True)

    def close(self) -> None:
        pass
