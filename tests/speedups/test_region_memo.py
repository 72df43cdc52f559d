"""Work reused across tray positions: the cells the database solves, every witness verified."""

from __future__ import annotations

import copy

import numpy as np
import pytest
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st

from pickstop.regions.pipeline import compute_tray_region
from pickstop.scene.load import parse_scene
from pickstop.scene.model import SceneError
from pickstop.speedups import region_memo
from pickstop.speedups.region_memo import ReuseCache, TrayAnchor
from tests.utils import assert_cells_verified, unlike_cells


def _moved(doc, tray_id, dx, dy):
    doc = copy.deepcopy(doc)
    for t in doc["trays"]:
        if t["id"] == tray_id:
            t["pose"]["x"] += dx
            t["pose"]["y"] += dy
    try:
        return parse_scene(doc)
    except SceneError:
        return None  # the move put the tray into a neighbour or off its table


def _from_scratch(planner, scene, tray_id, grow=True):
    """The region computed from scratch (``grow`` False: the cells the database solves alone,
    no growth from their witnesses)."""
    from unittest import mock

    from pickstop.regions import solve

    with mock.patch.object(solve, "grow", solve.grow if grow else lambda *a: 0):
        return compute_tray_region(planner, scene, scene.tray(tray_id), scene.base_yaw.yaws[0])


@settings(
    max_examples=10,
    deadline=None,
    suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.filter_too_much],
)
@given(
    tray=st.sampled_from(["tray_1", "tray_2", "tray_3"]),
    # moves that keep the tray on table A, clear of its neighbours, most of the time (88%)
    di=st.integers(-5, 5),
    dj=st.integers(-2, 8),
    fraction=st.sampled_from([0.0, 0.0, 0.0, 0.4]),
)
def test_moved_tray_regions_match_from_scratch(planner, paper_doc, tray, di, dj, fraction):
    """A tray moved by whole cells (and sometimes part of one) on a warm planner: every cell
    the database solves from scratch is there, and every cell whose witness is not the one
    from scratch (or that scratch lacks) has exactly verified witnesses; its neighbours
    likewise (the moved tray is in their way). Cells grown from neighbours' witnesses may
    differ where a neighbour kept another witness than scratch picks: few, and both ways."""
    scene0 = parse_scene(paper_doc)
    res = scene0.base_grid.resolution
    for t in scene0.task_trays:  # warm: every tray's refinements at the starting layout
        planner.tray_region(scene0, t)
    scene = _moved(paper_doc, tray, (di + fraction) * res, dj * res)
    assume(scene is not None)
    for tid in scene.task_trays:
        before = sum(m.hits for m in planner.reuse.values())
        reused = planner.compute_region(scene, tid, scene.base_yaw.yaws[0])
        if fraction == 0.0 and reused.reason is None:
            assert sum(m.hits for m in planner.reuse.values()) > before  # the memo was used
        scratch = _from_scratch(planner, scene, tid)
        solved = _from_scratch(planner, scene, tid, grow=False)
        assert not (solved.mask & ~reused.mask).any(), f"{tid}: a solved cell is missing"
        assert (scratch.mask & ~reused.mask).sum() <= 0.03 * scratch.mask.sum() + 1
        assert_cells_verified(planner, scene, reused, unlike_cells(scratch, reused))
        if tid == tray:
            assert reused.counts["feasible"] == len(reused.cells)


def test_anchor_keys_follow_the_tray():
    """Cells at the same offset from a tray get the same key wherever the tray stands."""
    from pickstop.scene.model import Pose, Tray

    def tray(x, y):
        return Tray(id="t", pose=Pose(x=x, y=y), inner_size=(0.2, 0.2))

    a = TrayAnchor.of(-1.0, -1.0, 0.025, tray(0.5, 0.3))
    b = TrayAnchor.of(-1.0, -1.0, 0.025, tray(0.5 + 7 * 0.025, 0.3 - 3 * 0.025))
    c = TrayAnchor.of(-1.0, -1.0, 0.025, tray(0.51, 0.3))
    assert a.phase == b.phase and a.phase != c.phase
    ix, iy = np.arange(5), np.arange(5)
    assert (a.cell_keys(ix, iy) == b.cell_keys(ix + 7, iy - 3)).all()
    assert len(set(a.cell_keys(ix, iy).tolist())) == 5


def test_a_preview_carries_only_the_same_tray(planner, paper_doc):
    """A region is carried to a tray of the same id only if it is the same tray (pose aside)
    under the same settings: another scene's tray_1, with other parts, is not carried."""
    scene = parse_scene(paper_doc)
    yaw = scene.base_yaw.yaws[0]
    planner.regions(scene)
    moved = _moved(paper_doc, "tray_1", -0.05, 0.0)
    assert moved is not None
    assert set(planner.known_regions(moved, [("tray_1", yaw)])) == {("tray_1", yaw)}
    other = copy.deepcopy(paper_doc)
    other["trays"][0]["parts"] = other["trays"][0]["parts"][:1]
    assert planner.known_regions(parse_scene(other), [("tray_1", yaw)]) == {}
    finer = copy.deepcopy(paper_doc)
    finer["floor_clearance"] = 0.02
    assert planner.known_regions(parse_scene(finer), [("tray_1", yaw)]) == {}


def _answers(n, dof=2, seed=0):
    """n cell answers with distinct values in every column."""
    from pickstop.speedups.region_memo import CellAnswers

    rng = np.random.default_rng(seed)
    lo = rng.uniform(-1, 0, (n, 3))
    return CellAnswers(
        rng.random(n) < 0.5, rng.normal(size=(n, dof)), rng.integers(0, 9, n), lo, lo + 1,
        rng.normal(size=(n, 2)), rng.normal(size=(n, 3, 3)), rng.normal(size=(n, 3, 3)),
        [rng.integers(0, 99, k).astype(np.int32) for k in rng.integers(0, 5, n)],
        [rng.normal(size=(k, dof)).astype(np.float32) for k in rng.integers(0, 3, n)],
    )  # fmt: skip


def _same_answers(a, b):
    for name in ("found", "theta", "grasp", "lo", "hi", "xy", "groups_lo", "groups_hi"):
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name), err_msg=name)
    assert len(a.rows) == len(b.rows) == len(a.refined) == len(b.refined)
    for x, y in zip(a.rows + a.refined, b.rows + b.refined, strict=True):
        np.testing.assert_array_equal(x, y)


def test_an_answer_table_gives_back_the_last_answer_of_each_cell():
    """Answers kept column by column, in batches that grow the table past its first capacity
    and answer some cells again: each cell gives back exactly its last answer and the
    surroundings it was computed in; a cell never answered has no row."""
    from pickstop.speedups.region_memo import AnswerTable

    table = AnswerTable()
    last: dict[int, tuple[object, int]] = {}
    rng = np.random.default_rng(1)
    for b in range(6):
        keys = rng.choice(300, size=int(rng.integers(1, 120)), replace=False)
        batch = _answers(len(keys), seed=b)
        table.put(keys, batch, b)
        for i, k in enumerate(keys.tolist()):
            last[k] = (batch.take(np.array([i])), b)
    keys = np.array([*sorted(last), 1000, 1001])
    row = table.find(keys)
    assert (row[-2:] == -1).all() and (row[:-2] >= 0).all() and len(table) == len(last)
    assert table.cols is not None
    for k, r in zip(keys[:-2].tolist(), row[:-2].tolist(), strict=True):
        _same_answers(table.cols.take(np.array([r])), last[k][0])
        assert table.around[r] == last[k][1]


def _box(owner, lo, hi):
    from pickstop.frames import T_yaw
    from pickstop.scene.world import Solid

    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    c = (lo + hi) / 2
    return Solid.box(T_yaw(c[0], c[1], c[2], 0.0), hi - lo, owner)


def _around(solids, x=0.0, y=0.0):
    from pickstop.scene.model import Pose, Tray
    from pickstop.speedups.region_memo import Surroundings

    return Surroundings.of(solids, Tray(id="t", pose=Pose(x=x, y=y), inner_size=(0.2, 0.2)))


def stale(old, new, lo, hi):
    """``(K,)`` where any change between surroundings ``old`` and ``new`` reaches the boxes."""
    from pickstop.speedups.region_memo import changes

    out = np.zeros(len(lo), bool)
    for c in changes(old, new):
        out |= c.hits(lo, hi)
    return out


def test_a_table_the_tray_slides_along_is_the_same_away_from_its_ends():
    """Seen from a tray moved 0.1 m along x, a long table is unchanged inside a box clear of
    the table's ends, and changed in a box that holds one of its ends; a neighbour left
    where it was has moved (relative to the tray) and changes only what is near it."""
    table = [-2.0, -0.5, 0.0], [2.0, 0.5, 0.72]
    old = _around([_box("table", *table), _box("nb", [0.5, -0.1, 0.72], [0.7, 0.1, 0.8])])
    new = _around([_box("table", *table), _box("nb", [0.5, -0.1, 0.72], [0.7, 0.1, 0.8])], x=0.1)
    lo = np.array([[-0.3, -0.3, 0.6], [-2.1, -0.3, 0.6], [0.35, -0.1, 0.7], [-0.3, 0.7, 0.0]])
    hi = np.array([[0.3, 0.3, 0.9], [-1.5, 0.3, 0.9], [0.45, 0.1, 0.75], [0.3, 0.9, 1.0]])
    # inside the table's top, far from its ends, the neighbour's old and new place, the table's
    # end, the neighbour's new place (0.4-0.6 relative), nothing at all
    assert stale(old, new, lo, hi).tolist() == [False, True, True, False]
    assert not stale(old, old, lo, hi).any()


def test_another_tray_that_moved_is_one_change_where_it_was_and_one_where_it_is():
    """The floor and walls of a neighbouring tray, seen from a tray that moved, are a change
    where any of them was and one where any of them is (two boxes to test, not two per wall):
    each wall's old and new place is stale, a box clear of the neighbour is not."""
    from pickstop.speedups.region_memo import changes

    walls = [
        ([0.5, -0.1, 0.72], [0.7, 0.1, 0.73]),  # floor
        ([0.5, -0.1, 0.73], [0.51, 0.1, 0.8]),
        ([0.69, -0.1, 0.73], [0.7, 0.1, 0.8]),
        ([0.5, -0.1, 0.73], [0.7, -0.09, 0.8]),
        ([0.5, 0.09, 0.73], [0.7, 0.1, 0.8]),
    ]
    tray = [_box("nb", lo, hi) for lo, hi in walls]
    old, new = _around(tray), _around(tray, x=0.05)
    assert len(changes(old, new)) == 2
    lo = np.array([w[0] for w in walls], float)
    hi = np.array([w[1] for w in walls], float)
    assert stale(old, new, lo, hi).all()  # where each was
    assert stale(old, new, lo - [0.05, 0, 0], hi - [0.05, 0, 0]).all()  # where each is
    clear = np.array([[-0.3, -0.3, 0.6]]), np.array([[0.3, 0.3, 0.9]])
    assert not stale(old, new, *clear).any()


def test_what_moved_without_a_partner_or_turned_is_a_change_wherever_it_was_or_is():
    """A solid that appears, disappears or turns (no longer axis-aligned) changes every box
    its bounds meet, before or after; a box away from all of them stays as it was."""
    from pickstop.frames import T_yaw
    from pickstop.scene.world import Solid

    a = _box("a", [0.0, 0.0, 0.0], [0.2, 0.2, 0.2])
    turned = Solid.box(T_yaw(0.1, 0.1, 0.1, 0.4), [0.2, 0.2, 0.2], "a")
    b = _box("b", [1.0, 1.0, 0.0], [1.2, 1.2, 0.2])
    near_a = (np.array([[0.15, 0.15, 0.1]]), np.array([[0.18, 0.18, 0.12]]))
    far = (np.array([[3.0, 3.0, 0.0]]), np.array([[3.1, 3.1, 0.1]]))
    near_b = (np.array([[1.1, 1.1, 0.1]]), np.array([[1.15, 1.15, 0.15]]))
    assert stale(_around([a]), _around([turned]), *near_a).all()
    assert not stale(_around([a]), _around([turned]), *far).any()
    assert stale(_around([a]), _around([a, b]), *near_b).all()  # appeared
    assert stale(_around([a, b]), _around([a]), *near_b).all()  # gone
    assert not stale(_around([a, b]), _around([a]), *near_a).any()


@pytest.mark.parametrize(
    ("moved", "di", "dj", "region_of"),
    [("tray_4", 2, -1, "tray_4"), ("tray_1", 2, 0, "tray_1"), ("tray_1", -4, 0, "tray_2")],
)
def test_remembered_answers_give_the_region_from_scratch(
    planner, paper_doc, moved, di, dj, region_of
):
    """A tray moved by whole cells (alone on its table; towards its neighbour; away from it,
    seen from the neighbour): answers and exact checks are taken from the memo where nothing
    near changed, witnesses where they are free of what is new; the region holds every cell
    the database solves from scratch, and each cell it solves otherwise (or that scratch
    lacks) has a witness coal verifies."""
    scene0 = parse_scene(paper_doc)
    res = scene0.base_grid.resolution
    yaw = scene0.base_yaw.yaws[0]
    planner.compute_region(scene0, region_of, yaw)
    scene = _moved(paper_doc, moved, di * res, dj * res)
    assert scene is not None
    before = sum(m.recalled for m in planner.reuse.values())
    reused = planner.compute_region(scene, region_of, yaw)
    recalled = sum(m.recalled for m in planner.reuse.values()) - before
    assert recalled > 0.3 * reused.counts["served"]
    scratch = _from_scratch(planner, scene, region_of)
    solved = _from_scratch(planner, scene, region_of, grow=False)
    assert not (solved.mask & ~reused.mask).any()
    unlike = unlike_cells(scratch, reused)
    assert len(unlike) < 0.2 * len(reused.cells)  # mostly the very witnesses of scratch
    assert_cells_verified(planner, scene, reused, unlike)


def test_a_cell_grown_before_keeps_its_witness_where_it_verifies(planner, paper_doc):
    """The tray alone on its table moved by whole cells: the cells grown into its region
    before are solved again by the witnesses they were grown with, checked exactly where
    they stand now, not refined anew from their neighbours'; every cell the database solves
    from scratch is kept, and each cell solved otherwise has a witness coal verifies."""
    scene0 = parse_scene(paper_doc)
    res, yaw = scene0.base_grid.resolution, scene0.base_yaw.yaws[0]
    first = planner.compute_region(scene0, "tray_4", yaw)
    assert first.counts["grown"] > 10
    scene = _moved(paper_doc, "tray_4", 2 * res, 0.0)
    assert scene is not None
    before = sum(m.regrown for m in planner.reuse.values())
    region = planner.compute_region(scene, "tray_4", yaw)
    regrown = sum(m.regrown for m in planner.reuse.values()) - before
    # each part of most of the cells grown before
    assert regrown > 0.5 * first.counts["grown"] * len(first.part_ids)
    solved = _from_scratch(planner, scene, "tray_4", grow=False)
    assert not (solved.mask & ~region.mask).any()
    assert_cells_verified(
        planner, scene, region, unlike_cells(_from_scratch(planner, scene, "tray_4"), region)
    )


def test_answers_that_held_outlive_the_surroundings_they_were_computed_in(
    planner, paper_doc, monkeypatch
):
    """A tray's neighbour moved again and again: the tray's answers that held are kept as
    answers in the surroundings of each layout, so they are still taken when the memo has long
    dropped the surroundings they were first computed in; the region still holds every cell
    the database solves from scratch, each with a verified witness."""

    monkeypatch.setattr(region_memo, "MAX_SURROUNDINGS", 2)
    scene0 = parse_scene(paper_doc)
    res, yaw = scene0.base_grid.resolution, scene0.base_yaw.yaws[0]
    planner.compute_region(scene0, "tray_2", yaw)
    for k in range(1, 5):  # four layouts: twice as many as the memo keeps surroundings
        scene = _moved(paper_doc, "tray_3", k * res, 0.0)
        assert scene is not None
        before = sum(m.recalled for m in planner.reuse.values())
        region = planner.compute_region(scene, "tray_2", yaw)
        recalled = sum(m.recalled for m in planner.reuse.values()) - before
        assert recalled > 0.5 * region.counts["served"], k
    solved = _from_scratch(planner, scene, "tray_2", grow=False)
    assert not (solved.mask & ~region.mask).any()
    assert_cells_verified(
        planner, scene, region, unlike_cells(_from_scratch(planner, scene, "tray_2"), region)
    )


def test_the_memos_together_stay_within_their_budget(monkeypatch):
    """However many trays are planned, the memos together are kept within MAX_BYTES: the
    least recently used go first, the one in use stays."""
    monkeypatch.setattr(region_memo, "MAX_BYTES", 10 * dict(region_memo.BYTES_PER)["answers"])
    cache = ReuseCache()
    for k in range(5):
        m = cache.memo(f"tray {k}")
        m.remember("db", "p", np.arange(4), _answers(4), 0)
    last = cache.memo("tray 4")
    assert (
        sum(m.approx_bytes() for m in cache.values()) <= 10 * dict(region_memo.BYTES_PER)["answers"]
    )
    assert list(cache)[-1] == "tray 4" and cache["tray 4"] is last and "tray 0" not in cache


def test_where_a_sample_shows_everything_changed_the_rest_is_not_tested():
    """Of many remembered things a change reaches, a sample is tested finely first; when
    nearly none of it still holds, the rest count as changed without being tested, and none
    is taken as it was."""

    class Everything:  # checks that all see the change
        def __init__(self, ids):
            self.owner = np.asarray(ids)

        def touched_by(self, changes, reached):
            return np.unique(np.concatenate(reached))

    memo = region_memo.RefineMemo()
    old = memo.around(_around([_box("nb", [0.0, 0.0, 0.0], [1.0, 1.0, 1.0])]))
    now = memo.around(_around([_box("nb", [0.0, 0.0, 0.0], [1.0, 1.0, 1.0])], x=0.3))
    n = 2 * region_memo.SAMPLE_FROM
    asked = []

    def checked(ids):
        asked.append(len(ids))
        return Everything(ids)

    box = np.tile([[0.2, 0.2, 0.2]], (n, 1)), np.tile([[0.8, 0.8, 0.8]], (n, 1))
    held = memo.held([old] * n, *box, now, checked)
    assert not held.any()
    assert asked == [len(range(0, n, region_memo.SAMPLE_STEP))]


def test_box_minus_covers_what_sticks_out_and_nothing_inside():
    """The slabs of a box outside another: none for the same box, the whole box for one
    apart, and for a shifted one pieces that hold every point of the box outside the cut and
    no point inside it."""
    from pickstop.speedups.region_memo import box_minus

    lo, hi = np.array([0.0, 0.0, 0.0]), np.array([1.0, 0.6, 0.7])
    assert box_minus(lo, hi, lo, hi) == []
    far = box_minus(lo, hi, lo + 5, hi + 5)
    assert len(far) == 1 and np.allclose(far[0][0], lo) and np.allclose(far[0][1], hi)
    rng = np.random.default_rng(3)
    for shift in ([0.1, 0.0, 0.0], [0.0, -0.2, 0.0], [0.3, 0.1, -0.05]):
        cut_lo, cut_hi = lo + shift, hi + shift
        pieces = box_minus(lo, hi, cut_lo, cut_hi)
        assert 1 <= len(pieces) <= 6
        pts = rng.uniform(lo, hi, (4000, 3))
        inside_cut = np.all((pts > cut_lo) & (pts < cut_hi), axis=1)
        in_piece = np.zeros(len(pts), bool)
        for a, b in pieces:
            assert np.all(a >= lo - 1e-12) and np.all(b <= hi + 1e-12)
            in_piece |= np.all((pts >= a) & (pts <= b), axis=1)
            assert not np.all((pts > a) & (pts < b) & inside_cut[:, None], axis=1).any()
        assert in_piece[~inside_cut].all()


def test_newcomers_are_what_stands_where_nothing_stood():
    """Seen from a tray moved 0.1 m along x: a long table it slides along is new only in the
    slab past its old end, a box left behind only where it did not stand before (relative to
    the tray), a post that turned up is new whole; surroundings compared with themselves have
    nothing new."""
    from pickstop.frames import T_yaw
    from pickstop.scene.world import Solid
    from pickstop.speedups.region_memo import RefineMemo

    table = _box("table", [-2.0, -0.5, 0.0], [2.0, 0.5, 0.72])
    nb = _box("nb", [0.5, -0.1, 0.72], [0.7, 0.1, 0.8])
    post = Solid.cylinder(T_yaw(1.0, 0.8, 0.5, 0.0), 0.05, 1.0, "post")
    memo = RefineMemo()
    old = memo.around(_around([table, nb]))
    now = memo.around(_around([table, nb, post], x=0.1))
    assert memo.newcomers(old, old) == ()
    new = {s.owner: s for s in memo.newcomers(old, now)}
    assert sorted(new) == ["nb", "post", "table"]
    for owner, want in (
        ("table", ([-2.1, -0.5, 0.0], [-2.0, 0.5, 0.72])),
        ("nb", ([0.4, -0.1, 0.72], [0.5, 0.1, 0.8])),
        ("post", ([0.85, 0.75, 0.0], [0.95, 0.85, 1.0])),
    ):
        lo, hi = new[owner].aabb()
        assert np.allclose(lo, want[0]) and np.allclose(hi, want[1]), owner
    assert new["post"].kind == "cylinder"


def test_a_witness_in_the_way_of_a_new_obstacle_is_not_kept(planner, paper_doc, monkeypatch):
    """A crate put on the table beside a tray, where the arm reaches past: witnesses clear
    of it are kept, those it meets are not, and every witness of the new region is verified
    by coal; the region still holds every cell the database solves from scratch."""
    from pickstop.speedups import cell_recall

    scene0 = parse_scene(paper_doc)
    yaw = scene0.base_yaw.yaws[0]
    planner.compute_region(scene0, "tray_4", yaw)
    doc = copy.deepcopy(paper_doc)
    tray = next(t for t in doc["trays"] if t["id"] == "tray_4")
    doc["obstacles"].append(
        {
            "id": "crate",
            "geometry": {"shape": "box", "size": [0.12, 0.2, 0.3]},
            "pose": {"x": tray["pose"]["x"] + 0.4, "y": tray["pose"]["y"] - 0.1, "z": 0.72},
        }
    )
    scene = parse_scene(doc)
    kept = []
    free_of = cell_recall.free_of_newcomers

    def recorded(*args):
        out = free_of(*args)
        kept.append(out)
        return out

    monkeypatch.setattr(cell_recall, "free_of_newcomers", recorded)
    after = planner.compute_region(scene, "tray_4", yaw)
    kept = np.concatenate(kept)
    assert kept.any() and not kept.all()
    assert_cells_verified(planner, scene, after, np.arange(len(after.cells)))
    solved = _from_scratch(planner, scene, "tray_4", grow=False)
    assert not (solved.mask & ~after.mask).any()
