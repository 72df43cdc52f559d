"""Dask: a LocalCluster build equals a local build; a killed worker loses no plan."""

from __future__ import annotations

import json
import os
import signal
from pathlib import Path

import pytest

distributed = pytest.importorskip("distributed")

from pickstop.distributed import dask_runner, plan_batch  # noqa: E402
from pickstop.reach.build import BuildParams  # noqa: E402
from pickstop.store.catalog import Catalog  # noqa: E402
from pickstop.store.reach_build import build  # noqa: E402

SCENE = Path(__file__).parents[1] / "examples" / "scenes" / "paper_experiment.json"


@pytest.fixture(scope="module")
def cluster_client():
    cluster = distributed.LocalCluster(
        n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None
    )
    client = distributed.Client(cluster)
    yield client
    client.close()
    cluster.close()


def _shards(folder: Path) -> list[tuple[int, str, int]]:
    cat = Catalog(folder)
    try:
        rows = cat.query("SELECT chunk, sha256, rows FROM reach_shards ORDER BY chunk")
        return [(r["chunk"], r["sha256"], r["rows"]) for r in rows]
    finally:
        cat.close()


def test_dask_build_equals_local_build(cluster_client, tiago, tmp_path):
    params = BuildParams(samples=60_000, chunk_size=20_000, seed=3)
    local = build(tiago, params, tmp_path / "local", workers=1)
    dask = build(tiago, params, tmp_path / "dask", runner=dask_runner(cluster_client))
    assert local["id"] == dask["id"] and dask["state"] == "complete"
    assert _shards(tmp_path / "local") == _shards(tmp_path / "dask")
    assert len(_shards(tmp_path / "dask")) == 3


def test_killed_worker_during_a_batch_still_yields_every_plan_once(cluster_client, region_db):
    folder, db = region_db
    doc = json.loads(SCENE.read_text())
    items = []
    for k in range(6):
        d = dict(doc, name=f"scene-{k}", sigma=0.03 + 0.01 * k)
        items.append((f"scene-{k}", d, SCENE.parent))
    pids = cluster_client.run(os.getpid)  # worker address -> pid
    results = {}
    killed = False
    for k, res in plan_batch(cluster_client, items, {"samples": 0}, folder, db.id):
        assert k not in results, "a scene was reported twice"
        results[k] = res
        if not killed:  # kill a worker while the rest of the batch is running
            os.kill(next(iter(pids.values())), signal.SIGKILL)
            killed = True
    assert sorted(results) == list(range(6))
    for k, res in results.items():
        assert "error" not in res, res
        assert res["format"] == "pickstop.plan" and res["scene"] == f"scene-{k}"
        assert res["parameters"]["sigma"] == pytest.approx(0.03 + 0.01 * k)


def test_a_layout_searched_on_dask_verifies_as_a_local_search_does(cluster_client, region_db,
                                                                   planner):  # fmt: skip
    """Candidate layouts ranked and verified as Dask tasks give the figures the same layouts
    get verified in this process (from scratch, whatever each worker did before)."""
    from pickstop.distributed import DaskEvaluator
    from pickstop.layout.search import SearchSettings, suggest
    from pickstop.layout.verify import scratch_planner
    from pickstop.scene.load import parse_scene
    from pickstop.scene.model import Order
    from pickstop.sequence.mix import mix_document, plan_mix
    from pickstop.sequence.plan_model import PlanOptions

    folder, db = region_db
    scene = parse_scene(json.loads(SCENE.read_text()))
    orders = [Order(id="task", trays=scene.task_trays)]
    options = PlanOptions(samples=20)
    ev = DaskEvaluator(cluster_client, SCENE.parent, folder, db.id, orders, options)
    settings = SearchSettings(step=0.2, turns=(0,), suggestions=1, shortlist=3)
    doc = suggest(planner, ev, scene, orders, ["tray_4"], options, settings)
    local = scratch_planner(planner)
    try:
        for s in doc.suggestions:
            mix = plan_mix(local, parse_scene(s.scene), orders, options)
            assert mix_document(mix).totals == s.after.totals
        before = plan_mix(local, scene, orders, options)
        assert mix_document(before).totals == doc.before.totals
    finally:
        local.regions.close()
