"""Choose the stops: fewest stops serving every required tray once, then the shortest route.

One CP-SAT model holds both: stop choice (x_c), which stop serves which tray (y_ct: every
required tray exactly once, only by a chosen stop that lies in its region, every chosen stop
serving at least one) and the route start -> chosen stops -> goal as a circuit whose unchosen
stops are skipped by self-loops. Lexicographic optimum: first the fewest stops, then, with the
count fixed, the shortest route (or the least predicted time).

A small model (a live edit's: a few trays, a few dozen candidates) is solved exactly by
enumeration instead (:func:`_by_enumeration`): every set of candidates of a size, kept where
each of its stops can serve a tray of its own and all of them serve every tray, each with its
best visiting order, on the same integer costs as the CP-SAT model. It is bounded by
:data:`ENUMERATION` (sets times visiting orders times stops), beyond which CP-SAT solves it.

Two optional constraints serve the expected-time objective: ``groups`` (candidates of one group
are alternatives: at most one of them is chosen) and ``n_stops`` (exactly that many stops: a
row of the trade-off between stops and time).
"""

from __future__ import annotations

import itertools
import math
import time
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any, Literal

import numpy as np
from ortools.sat.python import cp_model

from pickstop.errors import PickStopError

SCALE = 1000  # costs are integers: millimetres or milliseconds
#: Models of up to this many candidates are solved by one CP-SAT worker: it proves them
#: optimal faster than eight (which only contend for the cores on a model this small), and
#: one worker is deterministic, so the same inputs always give the same stops.
ONE_WORKER = 32
#: Route evaluations (candidate sets x visiting orders x stops) up to which a model is solved
#: by enumeration rather than CP-SAT; a few milliseconds of numpy at most.
ENUMERATION = 400_000
UNREACHABLE = 1 << 40  # the integer cost of a missing leg: any route using one is out


class InfeasiblePlanError(PickStopError):
    """No plan exists; the message names the trays and numbers involved."""

    exit_code = 3


@dataclass(frozen=True)
class Selection:
    order: tuple[int, ...]  # chosen candidates in visiting order
    serves: dict[str, int]  # required tray -> candidate serving it
    cost: float  # route length [m] or predicted time [s] of the chosen order
    optimal: bool  # proven by the solver
    seconds: float
    pruned: int = 0  # candidates ruled out by the route bound before the second phase


def select_stops(
    trays_of: list[frozenset[str]],
    required: list[str],
    cost: np.ndarray,
    *,
    objective: Literal["stops", "time"] = "stops",
    stop_cost: float = 0.0,
    time_limit: float = 20.0,
    workers: int | None = None,
    enumeration: int = ENUMERATION,
    n_stops: int | None = None,
    groups: Sequence[int] | None = None,
) -> Selection:
    """Pick stops among candidates.

    trays_of: trays each candidate can serve (candidate c is node c + 2).
    cost: (N + 2, N + 2) leg costs between nodes (0 = start, 1 = goal) [m or s].
    objective: "stops" minimises the number of stops, then the route cost; "time" minimises
    route cost + ``stop_cost`` per stop directly.
    workers: CP-SAT search workers (default: one up to :data:`ONE_WORKER` candidates, else 8).
    enumeration: the largest model (route evaluations) solved by enumeration (0: CP-SAT).
    n_stops: exactly this many stops (default: any number).
    groups: ``(N,)`` a group per candidate; at most one candidate of each group is chosen.
    """
    t0 = time.perf_counter()
    N = len(trays_of)
    assert cost.shape == (N + 2, N + 2)
    assert groups is None or len(groups) == N
    req = list(dict.fromkeys(required))
    servable = _servable(trays_of, req)
    icost = np.where(np.isfinite(cost), np.round(cost * SCALE), -1).astype(np.int64)
    stop_unit = round(stop_cost * SCALE) if objective == "time" else None
    group = np.arange(N) if groups is None else np.asarray(groups, np.int64)
    found = _by_enumeration(trays_of, req, icost, stop_unit, enumeration, n_stops, group)
    if found is not None:
        best_order, best_serves = found
        return Selection(best_order, best_serves, _cost(cost, best_order, objective, stop_cost),
                         True, time.perf_counter() - t0)  # fmt: skip
    m = _cover_model(req, servable, icost, group, n_stops)
    solver = cp_model.CpSolver()
    solver.parameters.num_workers = workers or (1 if N <= ONE_WORKER else 8)
    solver.parameters.max_time_in_seconds = time_limit
    optimal = True
    pruned = 0
    if objective == "stops":
        optimal, pruned = _fewest_stops_first(m, solver, req, icost)
    else:
        m.model.minimize(m.route + round(stop_cost * SCALE) * m.count)
    status = solver.solve(m.model)
    _check(status, req)
    optimal &= status == cp_model.OPTIMAL
    order, serves = _solution(m, solver)
    total = _cost(cost, order, objective, stop_cost)
    return Selection(order, serves, total, optimal, time.perf_counter() - t0, pruned)


@dataclass(frozen=True)
class _CoverModel:
    """The CP-SAT model and the variables read back from it."""

    model: cp_model.CpModel
    x: list[cp_model.IntVar]  # candidate c chosen
    y: dict[tuple[int, str], cp_model.IntVar]  # candidate c serves tray t
    arc_lits: list[tuple[int, int, cp_model.IntVar]]  # leg i -> j taken (nodes)
    route: Any  # the route cost [mm or ms]
    count: Any  # the number of stops


def _servable(trays_of: list[frozenset[str]], req: list[str]) -> dict[str, list[int]]:
    """The candidates that can serve each required tray; an error naming any tray none can."""
    servable = {t: [c for c in range(len(trays_of)) if t in trays_of[c]] for t in req}
    missing = [t for t in req if not servable[t]]
    if missing:
        raise InfeasiblePlanError(
            f"no candidate stop serves tray(s) {', '.join(missing)}", field="trays"
        )
    return servable


def _cover_model(
    req: list[str],
    servable: dict[str, list[int]],
    icost: np.ndarray,
    group: np.ndarray,
    n_stops: int | None,
) -> _CoverModel:
    """Stop choice, tray service and the route as one circuit, without an objective."""
    N = len(group)
    model = cp_model.CpModel()
    x = [model.new_bool_var(f"x{c}") for c in range(N)]
    y = {(c, t): model.new_bool_var(f"y{c}_{t}") for t in req for c in servable[t]}
    for t in req:
        model.add_exactly_one(y[c, t] for c in servable[t])
    for c in range(N):
        mine = [y[c, t] for t in req if (c, t) in y]
        for v in mine:
            model.add_implication(v, x[c])
        if mine:
            model.add_bool_or(mine).only_enforce_if(x[c])
        else:
            model.add(x[c] == 0)
    arc_lits = _route_circuit(model, x, icost)
    for g in np.unique(group):
        alike = np.flatnonzero(group == g)
        if len(alike) > 1:
            model.add_at_most_one(x[int(c)] for c in alike)
    route = sum(int(icost[i, j]) * lit for i, j, lit in arc_lits)
    count = sum(x)
    if n_stops is not None:
        model.add(count == n_stops)
    return _CoverModel(model, x, y, arc_lits, route, count)


def _route_circuit(
    model: cp_model.CpModel, x: list[cp_model.IntVar], icost: np.ndarray
) -> list[tuple[int, int, cp_model.IntVar]]:
    """A circuit through start (0), goal (1) and the chosen stops, closed by goal -> start,
    unchosen stops skipped by self-loops; the legs' literals (missing legs left out)."""
    N = len(x)
    arcs: list[tuple[int, int, Any]] = [(1, 0, model.new_constant(1))]
    arc_lits: list[tuple[int, int, cp_model.IntVar]] = []
    for i in range(N + 2):
        for j in range(N + 2):
            if i == j or (i, j) == (1, 0) or j == 0 or i == 1 or icost[i, j] < 0:
                continue
            lit = model.new_bool_var(f"a{i}_{j}")
            arcs.append((i, j, lit))
            arc_lits.append((i, j, lit))
            if i >= 2:
                model.add_implication(lit, x[i - 2])
            if j >= 2:
                model.add_implication(lit, x[j - 2])
    for c in range(N):
        arcs.append((c + 2, c + 2, x[c].negated()))
    model.add_circuit(arcs)
    return arc_lits


def _fewest_stops_first(
    m: _CoverModel, solver: cp_model.CpSolver, req: list[str], icost: np.ndarray
) -> tuple[bool, int]:
    """Solve for the fewest stops, fix that count and set the model to minimise the route:
    (the first phase proven optimal, candidates pruned by the route bound)."""
    N = len(m.x)
    m.model.minimize(m.count)
    status = solver.solve(m.model)
    _check(status, req)
    best = round(solver.objective_value)
    m.model.add(m.count == best)
    m.model.minimize(m.route)
    # Prune: a route through c is at least start -> c -> goal long (shortest paths obey
    # the triangle inequality), so c cannot beat the first phase's route if that is longer.
    # Each leg's cost is rounded by at most half a unit: the margin keeps the bound safe.
    incumbent = sum(int(icost[i, j]) for i, j, lit in m.arc_lits if solver.value(lit))
    pruned = 0
    for c in range(N):
        lb = icost[0, c + 2] + icost[c + 2, 1]
        if icost[0, c + 2] < 0 or icost[c + 2, 1] < 0 or lb > incumbent + N + 2:
            m.model.add(m.x[c] == 0)
            pruned += 1
    for c in range(N):  # warm start from the first phase's stops
        m.model.add_hint(m.x[c], bool(solver.value(m.x[c])))
    return status == cp_model.OPTIMAL, pruned


def _solution(m: _CoverModel, solver: cp_model.CpSolver) -> tuple[tuple[int, ...], dict[str, int]]:
    """The chosen candidates in visiting order and the candidate serving each tray."""
    succ = {i: j for i, j, lit in m.arc_lits if solver.value(lit)}
    order, node = [], 0
    while node != 1:
        node = succ[node]
        if node >= 2:
            order.append(node - 2)
    serves = {t: c for (c, t), v in m.y.items() if solver.value(v)}
    return tuple(order), serves


def _cost(
    cost: np.ndarray, order: tuple[int, ...], objective: Literal["stops", "time"], stop_cost: float
) -> float:
    """The route cost of visiting ``order`` (candidates) from start to goal, with the stops'
    own cost for the time objective."""
    nodes = [0, *(c + 2 for c in order), 1]
    total = float(sum(cost[a, b] for a, b in itertools.pairwise(nodes)))
    return total + stop_cost * len(order) if objective == "time" else total


def _by_enumeration(
    trays_of: list[frozenset[str]],
    req: list[str],
    icost: np.ndarray,
    stop_unit: int | None,
    limit: int,
    n_stops: int | None = None,
    group: np.ndarray | None = None,
) -> tuple[tuple[int, ...], dict[str, int]] | None:
    """The CP-SAT model's optimum by enumeration: ``(order, serves)``, or None if the model
    is beyond ``limit`` route evaluations (or has no plan: CP-SAT then says why).

    ``icost``: the model's integer leg costs (-1: no leg); ``stop_unit``: the integer cost
    of a stop for the time objective, None for the fewest stops then the shortest route. A
    set of k candidates is a plan if Hall's condition holds for it (every j of its stops
    cover at least j required trays: each can serve one of its own, exactly as the model's
    every-tray-once, every-stop-at-least-one) and together they cover every tray. Sets of
    each size are enumerated in lexicographic order, visiting orders in lexicographic order
    too, and the first best is taken: the same inputs always give the same stops. With
    ``n_stops`` only sets of that size are tried; with ``group`` (a group per candidate) none
    holding two candidates of a group."""
    N, T = len(trays_of), len(req)
    if T > 62 or N == 0:
        return None
    bit = {t: 1 << i for i, t in enumerate(req)}
    masks = np.array([sum(bit[t] for t in ts if t in bit) for ts in trays_of], np.int64)
    full = (1 << T) - 1
    c = np.where(icost < 0, UNREACHABLE, icost)
    budget = limit
    best: tuple[int, np.ndarray] | None = None  # (objective, order)
    for k in range(1, min(N, T) + 1):
        if best is not None and (stop_unit is None or stop_unit * k >= best[0]):
            break  # fewest stops found, or a larger set costs more in stops alone
        if n_stops is not None and k != n_stops:
            continue
        budget -= math.comb(N, k) * k
        if budget < 0:
            return None
        sets = _covering_sets(masks, k, full, group)
        if not len(sets):
            continue
        budget -= len(sets) * math.factorial(k) * (k + 1)
        if budget < 0:
            return None
        total, visit = _cheapest_visit(sets, c, (stop_unit or 0) * k)
        if total < UNREACHABLE and (best is None or total < best[0]):
            best = (total, visit)
    if best is None:
        return None
    order = tuple(int(v) for v in best[1])
    return order, _serves(trays_of, req, order)


def _covering_sets(
    masks: np.ndarray, k: int, full: int, group: np.ndarray | None = None
) -> np.ndarray:
    """``(S, k)`` the sets of k candidates (tray bits ``masks: (N,)``), in lexicographic
    order, that together serve every tray (``full``: all the bits) and each a tray of its own
    (:func:`_hall`); with ``group`` (a group per candidate), none holding two of a group."""
    sets = np.array(list(itertools.combinations(range(len(masks)), k)), np.int64).reshape(-1, k)
    sets = sets[np.bitwise_or.reduce(masks[sets], axis=1) == full]
    if group is not None and k > 1:
        g = np.sort(group[sets], axis=1)
        sets = sets[(np.diff(g, axis=1) != 0).all(axis=1)]
    return sets[_hall(masks[sets])]


def _cheapest_visit(sets: np.ndarray, c: np.ndarray, stops: int) -> tuple[int, np.ndarray]:
    """The least cost of a set of ``sets: (S, k)`` visited from start to goal in the integer
    costs ``c`` (candidate i at node i + 2) plus ``stops``, and its candidates in visiting
    order ``(k,)``: every order of every set, the first best in lexicographic order."""
    k = sets.shape[1]
    perms = np.array(list(itertools.permutations(range(k))), np.int64)
    nodes = sets[:, perms] + 2  # (S, P, k) every visiting order of every set
    total = c[0, nodes[..., 0]] + c[nodes[..., -1], 1] + stops
    for i in range(k - 1):
        total += c[nodes[..., i], nodes[..., i + 1]]
    s, p = divmod(int(np.argmin(total)), len(perms))
    return int(total[s, p]), nodes[s, p] - 2


def _hall(m: np.ndarray) -> np.ndarray:
    """``(S,)`` True where the stops of each set (their tray masks ``m: (S, k)``) can each
    serve a tray of its own: every j of them cover at least j trays."""
    S, k = m.shape
    ok = np.ones(S, bool)
    for sub in range(1, 1 << k):
        cols = [i for i in range(k) if sub >> i & 1]
        if len(cols) == 1:
            ok &= m[:, cols[0]] != 0
        else:
            ok &= np.bitwise_count(np.bitwise_or.reduce(m[:, cols], axis=1)) >= len(cols)
    return ok


def _serves(
    trays_of: list[frozenset[str]], req: list[str], order: tuple[int, ...]
) -> dict[str, int]:
    """Which stop of ``order`` serves each tray: first a tray of its own for every stop (a
    matching, by augmenting paths), then each other tray by the first stop on the route that
    can."""
    own: dict[str, int] = {}  # tray -> stop

    def augment(c: int, seen: set[str]) -> bool:
        for t in req:
            if t in trays_of[c] and t not in seen:
                seen.add(t)
                if t not in own or augment(own[t], seen):
                    own[t] = c
                    return True
        return False

    for c in order:
        if not augment(c, set()):
            raise AssertionError("the enumerated set breaks Hall's condition")
    return {t: own.get(t, next(c for c in order if t in trays_of[c])) for t in req}


def _check(status: Any, req: list[str]) -> None:
    if status in (cp_model.OPTIMAL, cp_model.FEASIBLE):
        return
    if status == cp_model.INFEASIBLE:
        raise InfeasiblePlanError(
            f"the candidate stops cannot serve trays {', '.join(req)} each exactly once on a "
            "route from start to goal (a stop or the goal may be unreachable)"
        )
    raise InfeasiblePlanError("the stop selection found no plan within its time limit")
