"""Choose the stops: fewest stops serving every required tray once, then the shortest route.

One CP-SAT model holds both: stop choice (x_c), which stop serves which tray (y_ct: every
required tray exactly once, only by a chosen stop that lies in its region, every chosen stop
serving at least one) and the route start -> chosen stops -> goal as a circuit whose unchosen
stops are skipped by self-loops. Lexicographic optimum: first the fewest stops, then, with the
count fixed, the shortest route (or the least predicted time).
"""

from __future__ import annotations

import itertools
import time
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
) -> Selection:
    """Pick stops among candidates.

    trays_of: trays each candidate can serve (candidate c is node c + 2).
    cost: (N + 2, N + 2) leg costs between nodes (0 = start, 1 = goal) [m or s].
    objective: "stops" minimises the number of stops, then the route cost; "time" minimises
    route cost + ``stop_cost`` per stop directly.
    workers: CP-SAT search workers (default: one up to :data:`ONE_WORKER` candidates, else 8).
    """
    t0 = time.perf_counter()
    N = len(trays_of)
    assert cost.shape == (N + 2, N + 2)
    req = list(dict.fromkeys(required))
    servable = {t: [c for c in range(N) if t in trays_of[c]] for t in req}
    missing = [t for t in req if not servable[t]]
    if missing:
        raise InfeasiblePlanError(
            f"no candidate stop serves tray(s) {', '.join(missing)}", field="trays"
        )
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
    # Route: a circuit through start (0), goal (1) and the chosen stops, closed by goal->start.
    icost = np.where(np.isfinite(cost), np.round(cost * SCALE), -1).astype(np.int64)
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
    route = sum(int(icost[i, j]) * lit for i, j, lit in arc_lits)
    n_stops = sum(x)
    solver = cp_model.CpSolver()
    solver.parameters.num_workers = workers or (1 if N <= ONE_WORKER else 8)
    solver.parameters.max_time_in_seconds = time_limit
    optimal = True
    pruned = 0
    if objective == "stops":
        model.minimize(n_stops)
        status = solver.solve(model)
        _check(status, req)
        optimal &= status == cp_model.OPTIMAL
        best = round(solver.objective_value)
        model.add(n_stops == best)
        model.minimize(route)
        # Prune: a route through c is at least start -> c -> goal long (shortest paths obey
        # the triangle inequality), so c cannot beat the first phase's route if that is longer.
        # Each leg's cost is rounded by at most half a unit: the margin keeps the bound safe.
        incumbent = sum(int(icost[i, j]) for i, j, lit in arc_lits if solver.value(lit))
        for c in range(N):
            lb = icost[0, c + 2] + icost[c + 2, 1]
            if icost[0, c + 2] < 0 or icost[c + 2, 1] < 0 or lb > incumbent + N + 2:
                model.add(x[c] == 0)
                pruned += 1
        for c in range(N):  # warm start from the first phase's stops
            model.add_hint(x[c], bool(solver.value(x[c])))
    else:
        model.minimize(route + round(stop_cost * SCALE) * n_stops)
    status = solver.solve(model)
    _check(status, req)
    optimal &= status == cp_model.OPTIMAL
    succ = {i: j for i, j, lit in arc_lits if solver.value(lit)}
    order, node = [], 0
    while node != 1:
        node = succ[node]
        if node >= 2:
            order.append(node - 2)
    serves = {t: c for (c, t), v in y.items() if solver.value(v)}
    nodes = [0, *(c + 2 for c in order), 1]
    total = float(sum(cost[a, b] for a, b in itertools.pairwise(nodes)))
    if objective == "time":
        total += stop_cost * len(order)
    return Selection(tuple(order), serves, total, optimal, time.perf_counter() - t0, pruned)


def _check(status: Any, req: list[str]) -> None:
    if status in (cp_model.OPTIMAL, cp_model.FEASIBLE):
        return
    if status == cp_model.INFEASIBLE:
        raise InfeasiblePlanError(
            f"the candidate stops cannot serve trays {', '.join(req)} each exactly once on a "
            "route from start to goal (a stop or the goal may be unreachable)"
        )
    raise InfeasiblePlanError("the stop selection found no plan within its time limit")
