"""Stop selection is lexicographically optimal: checked against brute force, by CP-SAT and
by the enumeration that solves small models."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from pickstop.scene.load import parse_scene
from pickstop.sequence import cover
from pickstop.sequence.cover import InfeasiblePlanError, select_stops
from pickstop.sequence.plan_model import PlanOptions


def _route(cost, order):
    nodes = [0, *(c + 2 for c in order), 1]
    return sum(cost[a, b] for a, b in itertools.pairwise(nodes))


def _assignable(trays_of, subset, required):
    """Each required tray served exactly once, each chosen stop serving at least one."""
    for pick in itertools.product(*[[c for c in subset if t in trays_of[c]] for t in required]):
        if set(pick) == set(subset):
            return True
    return False


def brute_force(trays_of, required, cost, stop_cost=None):
    """(stops, cost) of the best plan: the fewest stops then the shortest route, or with
    ``stop_cost`` the least route + stop_cost per stop; None if there is none."""
    N = len(trays_of)
    overall = None
    for k in range(1, N + 1):
        best = None
        for subset in itertools.combinations(range(N), k):
            if not _assignable(trays_of, subset, required):
                continue
            for perm in itertools.permutations(subset):
                r = _route(cost, perm) + (stop_cost or 0) * k
                if np.isfinite(r) and (best is None or r < best - 1e-9):
                    best = r
        if best is not None and stop_cost is None:
            return k, best
        if best is not None and (overall is None or best < overall[1] - 1e-9):
            overall = (k, best)
    return overall


@st.composite
def instances(draw, metric=True):
    n_trays = draw(st.integers(1, 4))
    trays = [f"t{i}" for i in range(n_trays)]
    n = draw(st.integers(1, 6))
    trays_of = [
        frozenset(draw(st.sets(st.sampled_from(trays), min_size=1, max_size=n_trays)))
        for _ in range(n)
    ]
    pts = np.array(
        draw(
            st.lists(
                st.tuples(st.integers(0, 20), st.integers(0, 20)), min_size=n + 2, max_size=n + 2
            )
        ),
        float,
    )
    cost = np.linalg.norm(pts[:, None] - pts[None], axis=-1)
    if not metric:  # any leg costs (the time objective makes no use of the triangle inequality)
        legs = draw(st.lists(st.integers(0, 9), min_size=(n + 2) ** 2, max_size=(n + 2) ** 2))
        cost = np.array(legs, float).reshape(n + 2, n + 2)
    # Some stops cut off (the base cannot get there: shortest paths keep the triangle
    # inequality, so such a stop has no leg at all), the goal too at times.
    for v in draw(st.sets(st.integers(1, n + 1), max_size=2)):
        cost[v, :] = cost[:, v] = np.inf
        cost[v, v] = 0.0
    return trays_of, trays, cost


def _check(sel, expected, trays_of, required):
    assert sel.optimal
    assert len(sel.order) == expected[0]
    assert sel.cost == pytest.approx(expected[1], abs=2e-2)
    assert set(sel.serves) == set(required)
    for t, c in sel.serves.items():
        assert t in trays_of[c] and c in sel.order
    assert set(sel.serves.values()) == set(sel.order)


@pytest.mark.parametrize("enumeration", [0, cover.ENUMERATION], ids=["cp-sat", "enumeration"])
@settings(max_examples=60, deadline=None)
@given(inst=instances())
def test_matches_brute_force(inst, enumeration):
    trays_of, required, cost = inst
    expected = brute_force(trays_of, required, cost)
    if expected is None:
        with pytest.raises(InfeasiblePlanError):
            select_stops(trays_of, required, cost, enumeration=enumeration)
        return
    _check(select_stops(trays_of, required, cost, enumeration=enumeration), expected, trays_of,
           required)  # fmt: skip


@pytest.mark.parametrize("enumeration", [0, cover.ENUMERATION], ids=["cp-sat", "enumeration"])
@settings(max_examples=80, deadline=None)
@given(
    inst=st.one_of(instances(), instances(metric=False)), stop_cost=st.sampled_from([0.0, 0.5, 3.0])
)
def test_least_time_matches_brute_force(inst, stop_cost, enumeration):
    trays_of, required, cost = inst
    expected = brute_force(trays_of, required, cost, stop_cost)
    kw = {"objective": "time", "stop_cost": stop_cost, "enumeration": enumeration}
    if expected is None:
        with pytest.raises(InfeasiblePlanError):
            select_stops(trays_of, required, cost, **kw)
        return
    sel = select_stops(trays_of, required, cost, **kw)
    # the count is not unique for the least time: the cost is, and the plan must be valid
    _check(sel, (len(sel.order), expected[1]), trays_of, required)


def test_enumeration_gives_way_to_cp_sat_beyond_its_bound(monkeypatch):
    trays_of = [frozenset({f"t{i}", f"t{(i + 1) % 9}"}) for i in range(9)]
    required = [f"t{i}" for i in range(9)]
    pts = np.array([[math.cos(a), math.sin(a)] for a in np.linspace(0, 6, 11)])
    cost = np.linalg.norm(pts[:, None] - pts[None], axis=-1)
    used = []
    real = cover.cp_model.CpSolver

    def solver():
        used.append(1)
        return real()

    monkeypatch.setattr(cover.cp_model, "CpSolver", solver)
    small = select_stops(trays_of, required, cost)
    assert not used
    large = select_stops(trays_of, required, cost, enumeration=1000)
    assert used
    assert len(small.order) == len(large.order) == 5
    assert small.cost == pytest.approx(large.cost, abs=1e-2)


def test_prefers_one_stop_in_an_intersection():
    # Trays a, b: separate stops right on the way, or one stop off the way serving both.
    trays_of = [frozenset("a"), frozenset("b"), frozenset("ab")]
    pts = np.array([[0, 0], [10, 0], [3, 0], [7, 0], [5, 4]], float)
    cost = np.linalg.norm(pts[:, None] - pts[None], axis=-1)
    sel = select_stops(trays_of, ["a", "b"], cost)
    assert sel.order == (2,) and sel.serves == {"a": 2, "b": 2}
    # Minimising time with a cheap stop picks the two stops on the straight line instead.
    fast = select_stops(trays_of, ["a", "b"], cost, objective="time", stop_cost=0.1)
    assert sorted(fast.order) == [0, 1]


def test_tray_without_candidate_is_named():
    cost = np.zeros((3, 3))
    with pytest.raises(InfeasiblePlanError, match="tray\\(s\\) b"):
        select_stops([frozenset("a")], ["a", "b"], cost)


@pytest.mark.parametrize("enumeration", [0, cover.ENUMERATION], ids=["cp-sat", "enumeration"])
def test_every_chosen_stop_serves_a_tray_even_where_a_detour_is_cheaper(enumeration):
    # Stops A (node 2) serving t, u, v, and B (3), C (4) serving t: start -> B -> C -> A ->
    # goal costs nothing, but B and C cannot both serve a tray of their own.
    cost = np.full((5, 5), 9.0)
    np.fill_diagonal(cost, 0.0)
    cost[0, 3] = cost[3, 4] = cost[4, 2] = cost[2, 1] = 0.0
    sel = select_stops([frozenset("tuv"), frozenset("t"), frozenset("t")], list("tuv"), cost,
                       objective="time", enumeration=enumeration)  # fmt: skip
    assert sel.cost == pytest.approx(9.0)
    assert set(sel.serves.values()) == set(sel.order)


def brute_force_fixed(trays_of, required, cost, stop_cost, k, groups):
    """The least route + stop_cost * k over plans of exactly ``k`` stops, none two of a
    group; None if there is none."""
    best = None
    for subset in itertools.combinations(range(len(trays_of)), k):
        if len({groups[c] for c in subset}) < k or not _assignable(trays_of, subset, required):
            continue
        for perm in itertools.permutations(subset):
            r = _route(cost, perm) + stop_cost * k
            if np.isfinite(r) and (best is None or r < best - 1e-9):
                best = r
    return best


@pytest.mark.parametrize("enumeration", [0, cover.ENUMERATION], ids=["cp-sat", "enumeration"])
@settings(max_examples=60, deadline=None)
@given(
    inst=st.one_of(instances(), instances(metric=False)),
    k=st.integers(1, 4),
    data=st.data(),
)
def test_fixed_count_and_groups_match_brute_force(inst, k, data, enumeration):
    """A row of the trade-off: exactly ``k`` stops, at most one candidate of each group."""
    trays_of, required, cost = inst
    groups = data.draw(st.lists(st.integers(0, 2), min_size=len(trays_of),
                                max_size=len(trays_of)))  # fmt: skip
    expected = brute_force_fixed(trays_of, required, cost, 1.5, k, groups)
    kw = {"objective": "time", "stop_cost": 1.5, "enumeration": enumeration, "n_stops": k,
          "groups": groups}  # fmt: skip
    if expected is None:
        with pytest.raises(InfeasiblePlanError):
            select_stops(trays_of, required, cost, **kw)
        return
    sel = select_stops(trays_of, required, cost, **kw)
    _check(sel, (k, expected), trays_of, required)
    assert len({groups[c] for c in sel.order}) == k


def test_larger_sigma_never_needs_fewer_stops(stop_planner, paper_doc):
    scene = parse_scene(paper_doc)
    counts = []
    for sigma in (0.0, 0.05, 0.1, 0.15):
        try:
            counts.append(
                stop_planner.plan(scene, PlanOptions(sigma=sigma, samples=0)).totals.stops
            )
        except InfeasiblePlanError:
            counts.append(math.inf)
    assert counts == sorted(counts)


def test_time_objective_is_no_slower(stop_planner, paper_doc):
    scene = parse_scene(paper_doc)
    by_stops = stop_planner.plan(scene, PlanOptions(samples=0))
    by_time = stop_planner.plan(scene, PlanOptions(samples=0, objective="time"))
    assert by_time.totals.time.total <= by_stops.totals.time.total + 1e-6
