"""Stop selection is lexicographically optimal: checked against brute force."""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from pickstop.sequence.cover import InfeasiblePlanError, select_stops


def _route(cost, order):
    nodes = [0, *(c + 2 for c in order), 1]
    return sum(cost[a, b] for a, b in itertools.pairwise(nodes))


def _assignable(trays_of, subset, required):
    """Each required tray served exactly once, each chosen stop serving at least one."""
    for pick in itertools.product(*[[c for c in subset if t in trays_of[c]] for t in required]):
        if set(pick) == set(subset):
            return True
    return False


def brute_force(trays_of, required, cost):
    N = len(trays_of)
    for k in range(1, N + 1):
        best = None
        for subset in itertools.combinations(range(N), k):
            if not _assignable(trays_of, subset, required):
                continue
            for perm in itertools.permutations(subset):
                r = _route(cost, perm)
                if best is None or r < best - 1e-9:
                    best = r
        if best is not None:
            return k, best
    return None


@st.composite
def instances(draw):
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
    return trays_of, trays, cost


@settings(max_examples=60, deadline=None)
@given(instances())
def test_matches_brute_force(inst):
    trays_of, required, cost = inst
    expected = brute_force(trays_of, required, cost)
    if expected is None:
        with pytest.raises(InfeasiblePlanError):
            select_stops(trays_of, required, cost)
        return
    sel = select_stops(trays_of, required, cost)
    assert sel.optimal
    assert len(sel.order) == expected[0]
    assert sel.cost == pytest.approx(expected[1], abs=2e-3)
    assert set(sel.serves) == set(required)
    for t, c in sel.serves.items():
        assert t in trays_of[c] and c in sel.order
    assert set(sel.serves.values()) == set(sel.order)


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
