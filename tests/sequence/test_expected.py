"""The expected-time selection against brute force over every set of stops, every sharing of
the trays among them and every visiting order, by enumeration and by CP-SAT."""

from __future__ import annotations

import itertools
import json
import math
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from pickstop.scene.load import parse_scene
from pickstop.sequence import expected
from pickstop.sequence.cover import InfeasiblePlanError, select_stops
from pickstop.sequence.failure import FailureCosts, failure_time
from pickstop.sequence.plan_model import PlanOptions

EXAMPLES = Path(__file__).parents[2] / "examples" / "scenes"

COSTS = FailureCosts(15.0, 2, 300.0)
STOP = 8.0


def solve(trays_of, required, cost, stop_cost, n_stops, groups):
    return select_stops(trays_of, required, cost, objective="time", stop_cost=stop_cost,
                        n_stops=n_stops, groups=groups, enumeration=0)  # fmt: skip


def brute_force(trays_of, required, travel, estimates):
    """k -> least route + stops + failures with exactly k stops."""
    best = {}
    N = len(trays_of)
    for k in range(1, N + 1):
        for subset in itertools.combinations(range(N), k):
            options = [[c for c in subset if t in trays_of[c]] for t in required]
            share = None
            for pick in itertools.product(*options):
                if set(pick) != set(subset):
                    continue
                f = sum(
                    float(failure_time(estimates[c][frozenset(
                        t for t, w in zip(required, pick, strict=True) if w == c)], COSTS))
                    for c in subset
                )  # fmt: skip
                share = f if share is None else min(share, f)
            if share is None:
                continue
            for perm in itertools.permutations(subset):
                nodes = [0, *(c + 2 for c in perm), 1]
                r = sum(travel[a, b] for a, b in itertools.pairwise(nodes))
                total = r + STOP * k + share
                if np.isfinite(total) and total < best.get(k, np.inf):
                    best[k] = total
    return best


@st.composite
def instances(draw):
    T = draw(st.integers(1, 4))
    required = [f"t{i}" for i in range(T)]
    N = draw(st.integers(1, 5))
    trays_of = [sorted(draw(st.sets(st.sampled_from(required), min_size=1))) for _ in range(N)]
    pts = np.array(draw(st.lists(st.tuples(st.integers(0, 30), st.integers(0, 30)),
                                 min_size=N + 2, max_size=N + 2)), float)  # fmt: skip
    travel = np.linalg.norm(pts[:, None] - pts[None], axis=-1)
    if draw(st.booleans()):  # a candidate cut off
        v = draw(st.integers(2, N + 1))
        travel[v, :] = travel[:, v] = np.inf
        travel[v, v] = 0.0
    # Each tray's own odds at each candidate; a set succeeds when all of its trays do (the
    # estimates' own monotony: a larger set never succeeds more often).
    odds = {(c, t): draw(st.floats(0.3, 1.0)) for c in range(N) for t in trays_of[c]}
    estimates = [
        {s: float(np.prod([odds[c, t] for t in s])) for s in expected.tray_sets(trays_of[c])}
        for c in range(N)
    ]
    return trays_of, required, travel, estimates


@pytest.mark.parametrize("enumeration", [0, expected.ROUTES], ids=["cp-sat", "enumeration"])
@settings(max_examples=40, deadline=None)
@given(inst=instances())
def test_least_expected_time_and_every_row_match_brute_force(inst, enumeration):
    trays_of, required, travel, estimates = inst
    want = brute_force(trays_of, required, travel, estimates)
    ks = list(range(1, len(required) + 1))
    args = (trays_of, required, travel, STOP, estimates, COSTS, solve)
    if not want:
        with pytest.raises(InfeasiblePlanError):
            expected.select(*args, enumeration=enumeration)
        return
    best = expected.select(*args, enumeration=enumeration)[0]
    assert best.cost == pytest.approx(min(want.values()), abs=2e-2)
    rows = expected.select(*args, ks, enumeration=enumeration)
    assert {k for k in rows if k} == set(want)
    for k, sel in rows.items():
        assert sel.cost == pytest.approx(min(want.values()) if k == 0 else want[k], abs=2e-2)
        # every tray served once, by a stop that can, every stop serving one at least
        assert set(sel.serves) == set(required)
        assert all(t in trays_of[c] for t, c in sel.serves.items())
        assert set(sel.serves.values()) == set(sel.order) and len(set(sel.order)) == len(sel.order)
        # the cost is what the stops' shares of the trays make it
        shares = expected.served(sel)
        nodes = [0, *(c + 2 for c in sel.order), 1]
        route = sum(travel[a, b] for a, b in itertools.pairwise(nodes))
        fails = sum(float(failure_time(estimates[c][s], COSTS)) for c, s in shares.items())
        assert sel.cost == pytest.approx(route + STOP * len(sel.order) + fails, abs=2e-2)


def test_two_stops_beat_one_that_often_fails():
    """One stop serving both trays at 50%, or two on the way at 99% each."""
    trays_of = [["a", "b"], ["a"], ["b"]]
    pts = np.array([[0, 0], [10, 0], [5, 1], [3, 0], [7, 0]], float)
    travel = np.linalg.norm(pts[:, None] - pts[None], axis=-1)
    estimates = [
        {frozenset("ab"): 0.5, frozenset("a"): 0.9, frozenset("b"): 0.9},
        {frozenset("a"): 0.99},
        {frozenset("b"): 0.99},
    ]
    best = expected.select(trays_of, ["a", "b"], travel, STOP, estimates, COSTS, solve)[0]
    assert sorted(best.order) == [1, 2]
    sure = [{s: 1.0 for s in e} for e in estimates]  # never failing: one stop is best
    assert expected.select(trays_of, ["a", "b"], travel, STOP, sure, COSTS, solve)[0].order == (0,)


@pytest.mark.parametrize("k", [7, 8])
def test_held_karp_finds_the_shortest_visiting_order(k, monkeypatch):
    rng = np.random.default_rng(k)
    c = rng.integers(0, 1000, (k + 4, k + 4))
    c[rng.random(c.shape) < 0.1] = expected.UNREACHABLE  # some legs missing
    sets = np.array([rng.permutation(k + 2)[:k] for _ in range(5)])
    got = expected._routes(sets, c)
    monkeypatch.setattr(expected, "PERMUTED", k)  # every visiting order instead
    assert np.array_equal(got, expected._routes(sets, c))
    for s, want in zip(sets, got, strict=True):
        order = [0, *(v + 2 for v in expected._order(s, c)), 1]
        monkeypatch.setattr(expected, "PERMUTED", k - 1)
        held = [0, *(v + 2 for v in expected._order(s, c)), 1]
        monkeypatch.setattr(expected, "PERMUTED", k)
        for o in (order, held):
            assert sorted(o[1:-1]) == sorted(v + 2 for v in s)
            assert sum(c[a, b] for a, b in itertools.pairwise(o)) == want


@pytest.mark.parametrize("name", ["paper_experiment", "five_trays", "factory_cell", "rack_cell"])
def test_expected_time_plan_is_never_worse_in_expected_time(stop_planner, name):
    """On the same candidates (the same rule, nothing rejected differently), no objective's
    plan has a lower expected time than the expected-time objective's; its trade-off holds a
    row for its own number of stops, with its expected time, and none lower."""
    scene = parse_scene(json.loads((EXAMPLES / f"{name}.json").read_text()))
    compared = 0
    for rule in ("sigma", "success"):
        plans = {}
        for objective in ("stops", "time", "expected-time"):
            try:
                plans[objective] = stop_planner.plan(
                    scene, PlanOptions(rule=rule, objective=objective, samples=0)
                )
            except InfeasiblePlanError:
                continue
        if "expected-time" not in plans:
            assert not plans
            continue
        best = plans.pop("expected-time")
        t = best.totals.time
        assert t.expected == pytest.approx(t.total + t.failures)
        assert all(s.failures.source == "estimate" for s in best.stops)
        rows = {r.stops: r for r in best.tradeoff}
        mine = rows[len(best.stops)]
        assert mine.chosen and sum(r.chosen for r in rows.values()) == 1
        assert mine.expected_time == pytest.approx(t.expected, abs=1e-2)
        assert mine.success == pytest.approx(math.prod(s.estimated_success for s in best.stops))
        assert all(r.expected_time >= mine.expected_time - 1e-2 for r in rows.values())
        assert all(r.expected_time >= r.time for r in rows.values())
        for other in plans.values():
            if [c.status == "rejected" for c in other.candidates] != [
                c.status == "rejected" for c in best.candidates
            ]:
                continue  # a stop failed its exact check in one of them: other candidates
            assert t.expected <= other.totals.time.expected + 1e-2
            assert rows[len(other.stops)].expected_time <= other.totals.time.expected + 1e-2
            compared += 1
    assert compared >= 2
