"""The expected-time objective: travel, stops, picks and failed arrivals in one sum.

A stop's expected failure time depends on the trays it serves (its success is that of landing
where all of them are graspable), so the objective of a set of stops is its best route's time,
``stop_time`` per stop, and the least sum of failure times over the ways its stops can share
the trays (each tray served once, each stop serving at least one).

:func:`select` solves it exactly. A small model is enumerated (:func:`_by_enumeration`): every
set of k candidates covering the trays under Hall's condition, each with its best visiting order
(as :mod:`~pickstop.sequence.cover` does) and its best sharing of the trays (a dynamic programme
over sets of trays, stop by stop). Beyond the bound, each candidate becomes one node per set of
trays it can serve, costing that set's failures on arrival (:func:`expand`), solved by
:func:`~pickstop.sequence.cover.select_stops` with at most one node per candidate (its
``groups``); a node serving less than its set costs no less than the node of what it serves, so
that optimum is the same. For the trade-off the same is solved with exactly k stops, each k.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from pickstop.sequence.cover import (
    SCALE,
    UNREACHABLE,
    InfeasiblePlanError,
    Selection,
    _covering_sets,
)
from pickstop.sequence.failure import FailureCosts, failure_time

MAX_TRAYS = 10  # trays up to which sets of stops are enumerated
ROUTES = 60_000_000  # route evaluations (sets x orders x legs, or Held-Karp's steps) at most
PERMUTED = 5  # stops up to which a set's visiting orders are all tried (beyond: Held-Karp)
SHARING = 180_000_000  # steps of the sharing programme (sets x stops x parts x tray masks)

#: A stop selection: ``solve(trays_of, required, cost, stop_cost, n_stops, groups)``, the
#: ``time`` objective of :func:`~pickstop.sequence.cover.select_stops` (memoised by the planner).
Solve = Callable[
    [list[frozenset[str]], list[str], np.ndarray, float, int | None, tuple[int, ...]], Selection
]


@dataclass(frozen=True)
class Nodes:
    """Nodes of the CP-SAT model: a candidate and the trays it serves, with that set's
    expected failure time [s]."""

    cands: tuple[int, ...]
    trays: tuple[frozenset[str], ...]
    extra: np.ndarray  # (n,) [s]


def tray_sets(trays: Sequence[str]) -> list[frozenset[str]]:
    """Every non-empty set of ``trays``, largest first."""
    return [
        frozenset(s) for k in range(len(trays), 0, -1) for s in itertools.combinations(trays, k)
    ]


def served(sel: Selection) -> dict[int, frozenset[str]]:
    """The trays each chosen candidate serves."""
    out: dict[int, set[str]] = {c: set() for c in sel.order}
    for t, c in sel.serves.items():
        out[c].add(t)
    return {c: frozenset(ts) for c, ts in out.items()}


def select(
    trays_of: Sequence[Sequence[str]],
    required: list[str],
    travel: np.ndarray,
    stop_time: float,
    estimates: Sequence[Mapping[frozenset[str], float]],
    costs: FailureCosts,
    solve: Solve,
    ks: Sequence[int] | None = None,
    enumeration: int = ROUTES,
) -> dict[int, Selection]:
    """The least expected-time selection (key 0), and with ``ks`` the least with exactly k
    stops for each k of ``ks`` (a k without any plan is left out). Costs exclude the picks.

    trays_of: per candidate, the required trays it can serve; travel: ``(N + 2, N + 2)`` leg
    times [s] (0 = start, 1 = goal; inf: no way); estimates: per candidate, the success of
    each set of its trays. Raises :class:`InfeasiblePlanError` if no plan exists."""
    N, T = len(trays_of), len(required)
    assert travel.shape == (N + 2, N + 2) and len(estimates) == N
    bit = {t: 1 << i for i, t in enumerate(required)}
    masks = np.array([sum(bit[t] for t in ts) for ts in trays_of], np.int64)
    wanted = sorted(set(ks)) if ks is not None else list(range(1, min(N, T) + 1))
    found: Found = {k: False for k in wanted}  # too many trays: CP-SAT for every k
    extra = np.zeros((N, 1), np.int64)
    if T <= MAX_TRAYS:
        extra = np.full((N, 1 << T), UNREACHABLE, np.int64)  # [ms] per candidate, tray mask
        for c, ts in enumerate(trays_of):
            for s in tray_sets(ts):
                m = sum(bit[t] for t in s)
                extra[c, m] = round(float(failure_time(estimates[c][s], costs)) * SCALE)
        icost = np.where(np.isfinite(travel), np.round(travel * SCALE), -1).astype(np.int64)
        found = _by_enumeration(masks, extra, icost, round(stop_time * SCALE), wanted,
                                ks is None, enumeration)  # fmt: skip
    rows = {
        k: _selection(v, required, travel, stop_time, extra)
        for k, v in found.items()
        if v is not None and v is not False
    }
    beyond = [k for k, v in found.items() if v is False]
    args = (trays_of, required, travel, stop_time, estimates, costs, solve)
    if ks is None:
        best = _by_nodes(*args, None) if beyond else _best(rows)
    else:
        for k in beyond:
            got = _by_nodes(*args, k)
            if got is not None:
                rows[k] = got
        best = _best(rows)
    if best is None:
        raise InfeasiblePlanError(
            f"the candidate stops cannot serve trays {', '.join(required)} each exactly once "
            "on a route from start to goal"
        )
    return {**rows, 0: best} if ks is not None else {0: best}


def _best(rows: dict[int, Selection]) -> Selection | None:
    """The least-cost selection of ``rows`` (the fewest stops on a tie)."""
    return min(rows.values(), key=lambda s: (round(s.cost * SCALE), len(s.order)), default=None)


def expand(
    trays_of: Sequence[Sequence[str]],
    estimates: Sequence[Mapping[frozenset[str], float]],
    costs: FailureCosts,
) -> Nodes:
    """The CP-SAT model's nodes: each candidate with each set of its trays, but a set whose
    failures cost, in the solver's integer units, what a larger set's of the same candidate
    cost (the larger one does all it does for no more)."""
    cands, trays, extras = [], [], []
    for c, ts in enumerate(trays_of):
        sets = tray_sets(ts)
        units = {s: round(float(failure_time(estimates[c][s], costs)) * SCALE) for s in sets}
        for s in sets:
            if not any(s < o and units[o] <= units[s] for o in sets):
                cands.append(c)
                trays.append(s)
                extras.append(float(failure_time(estimates[c][s], costs)))
    return Nodes(tuple(cands), tuple(trays), np.array(extras, float))


def _by_nodes(
    trays_of: Sequence[Sequence[str]],
    required: list[str],
    travel: np.ndarray,
    stop_time: float,
    estimates: Sequence[Mapping[frozenset[str], float]],
    costs: FailureCosts,
    solve: Solve,
    n_stops: int | None,
) -> Selection | None:
    """The selection by CP-SAT over :func:`expand`'s nodes (None: no plan of ``n_stops``)."""
    nodes = expand(trays_of, estimates, costs)
    at = [0, 1, *(c + 2 for c in nodes.cands)]
    cost = travel[np.ix_(at, at)].copy()
    cost[:, 2:] += nodes.extra[None, :]  # each arrival at a node charged its failures
    try:
        sel = solve(list(nodes.trays), required, cost, stop_time, n_stops, nodes.cands)
    except InfeasiblePlanError:
        if n_stops is None:
            raise
        return None
    return Selection(
        tuple(nodes.cands[n] for n in sel.order),
        {t: nodes.cands[n] for t, n in sel.serves.items()},
        sel.cost,
        sel.optimal,
        sel.seconds,
        sel.pruned,
    )


#: One row found by enumeration: (order, the tray mask each stop serves), False if beyond the
#: bound; a k with no plan is absent.
Found = dict[int, "tuple[tuple[int, ...], tuple[int, ...]] | bool"]


def _by_enumeration(
    masks: np.ndarray,
    extra: np.ndarray,
    icost: np.ndarray,
    stop_unit: int,
    ks: list[int],
    early: bool,
    limit: int,
) -> Found:
    """The least-cost set of each size k of ``ks`` by enumeration (see the module).

    masks: ``(N,)`` tray bits per candidate; extra: ``(N, 2^T)`` integer failure cost of
    serving each tray mask (:data:`UNREACHABLE`: it cannot); icost: integer leg costs (-1:
    none). ``early``: stop at the first k whose stops alone cost more than the best so far
    (the rest are then absent). Within each k, sets and visiting orders in lexicographic
    order, the first best taken: the same inputs always give the same stops."""
    m = _Enumeration.of(masks, extra, icost, stop_unit)
    N = len(masks)
    budget, sharing, best = limit, SHARING, None
    out: Found = {}
    for k in ks:
        if early and best is not None and stop_unit * k >= best:
            break
        if k > N:
            continue
        budget -= math.comb(N, k) * k
        if budget < 0:
            out[k] = False
            continue
        sets = _covering_sets(masks, k, m.full)
        if not len(sets):
            continue
        budget -= len(sets) * _route_work(k)
        if budget < 0:
            out[k] = False
            continue
        total, sharing = _totals(m, sets, sharing)
        if sharing < 0:
            out[k] = False
            continue
        s = int(np.argmin(total))
        if total[s] >= UNREACHABLE:
            continue
        order = _order(sets[s], m.c)
        out[k] = (order, _parts(sets[s], masks, extra, order))
        best = int(total[s]) if best is None else min(best, int(total[s]))
    return out


@dataclass(frozen=True)
class _Enumeration:
    """:func:`_by_enumeration`'s model in integer units: per candidate its tray bits and the
    failure cost of each tray mask, the leg costs, a stop's cost."""

    masks: np.ndarray  # (N,) tray bits per candidate
    extra: np.ndarray  # (N, 2^T) failure cost per tray mask (UNREACHABLE: it cannot serve it)
    c: np.ndarray  # (N + 2, N + 2) leg costs (UNREACHABLE: no leg)
    stop_unit: int
    full: int  # every tray's bit
    widest: int  # the most trays a candidate serves
    cheapest: np.ndarray  # (N,) the least a stop's part can cost

    @classmethod
    def of(
        cls, masks: np.ndarray, extra: np.ndarray, icost: np.ndarray, stop_unit: int
    ) -> _Enumeration:
        N, T = len(masks), extra.shape[1].bit_length() - 1
        c = np.where(icost < 0, UNREACHABLE, icost)
        widest = int(max(np.bitwise_count(masks))) if N else 0
        cheapest = extra[:, 1:].min(axis=1)
        return cls(masks, extra, c, stop_unit, (1 << T) - 1, widest, cheapest)


def _totals(m: _Enumeration, sets: np.ndarray, sharing: int) -> tuple[np.ndarray, int]:
    """``(S,)`` each set's least cost (route, stops, failures; above :data:`UNREACHABLE`
    where not worked out) and the sharing programme's budget left (negative: spent). The
    sharing is worked out only where it can matter, cheapest bound first: a set whose route,
    stops and cheapest parts already cost more than a set's whole is out."""
    k = sets.shape[1]
    lower = _routes(sets, m.c) + m.stop_unit * k + m.cheapest[sets].sum(axis=1)
    total = np.full(len(sets), UNREACHABLE * (k + 3), np.int64)
    for chunk in np.array_split(np.argsort(lower, kind="stable"), max(1, len(sets) // 256)):
        if lower[chunk[0]] > total.min() or lower[chunk[0]] >= UNREACHABLE:
            break
        sharing -= len(chunk) * k * (1 << m.widest) * (m.full + 1)
        if sharing < 0:
            break
        total[chunk] = (
            lower[chunk]
            - m.cheapest[sets[chunk]].sum(axis=1)
            + _sharing(sets[chunk], m.masks, m.extra)[:, m.full]
        )
    return total, sharing


def _route_work(k: int) -> int:
    """Route evaluations per set of ``k`` stops (:func:`_routes`)."""
    return math.factorial(k) * (k + 1) if k <= PERMUTED else (1 << k) * k * k


def _routes(sets: np.ndarray, c: np.ndarray) -> np.ndarray:
    """``(S,)`` each set's shortest route from start through all its stops to goal, in the
    integer costs ``c`` (nodes: 0 start, 1 goal, candidate i at i + 2): every visiting order
    up to :data:`PERMUTED` stops, Held-Karp's programme beyond."""
    k = sets.shape[1]
    if k <= PERMUTED:
        perms = np.array(list(itertools.permutations(range(k))), np.int64)
        nodes = sets[:, perms] + 2  # (S, P, k) every visiting order of every set
        route = c[0, nodes[..., 0]] + c[nodes[..., -1], 1]
        for i in range(k - 1):
            route += c[nodes[..., i], nodes[..., i + 1]]
        return route.min(axis=1)
    dp = _held_karp(sets, c)
    return (dp[:, -1, :] + c[sets + 2, 1]).min(axis=1)


def _held_karp(sets: np.ndarray, c: np.ndarray) -> np.ndarray:
    """``(S, 2^k, k)``: the shortest way from start through the stops of each visited mask,
    ending at each of them."""
    S, k = sets.shape
    n = sets + 2
    legs = c[n[:, :, None], n[:, None, :]]  # (S, k, k)
    dp = np.full((S, 1 << k, k), 1 << 62, np.int64)  # (set, visited mask, last stop)
    dp[:, 1 << np.arange(k), np.arange(k)] = c[0, n]
    for mask in range(1, 1 << k):
        via = (dp[:, mask, :, None] + legs).min(axis=1)  # (S, next)
        for j in range(k):
            if not mask >> j & 1:
                nxt = mask | 1 << j
                dp[:, nxt, j] = np.minimum(dp[:, nxt, j], via[:, j])
    return dp


def _order(stops: np.ndarray, c: np.ndarray) -> tuple[int, ...]:
    """A shortest visiting order of ``stops``: the first in lexicographic order up to
    :data:`PERMUTED` stops, else Held-Karp's (traced back, the first best at each step)."""
    k = len(stops)
    if k <= PERMUTED:
        perms = np.array(list(itertools.permutations(stops.tolist())), np.int64) + 2
        route = c[0, perms[:, 0]] + c[perms[:, -1], 1]
        for i in range(k - 1):
            route += c[perms[:, i], perms[:, i + 1]]
        return tuple(int(v) - 2 for v in perms[int(np.argmin(route))])
    dp = _held_karp(stops[None], c)[0]
    n = stops + 2
    mask, last = (1 << k) - 1, int(np.argmin(dp[-1] + c[n, 1]))
    back = [last]
    while mask != 1 << last:
        prev = mask ^ 1 << last
        ways = dp[prev] + c[n, n[last]]
        ways[[j for j in range(k) if not prev >> j & 1]] = 1 << 62
        mask, last = prev, int(np.argmin(ways))
        back.append(last)
    return tuple(int(stops[j]) for j in reversed(back))


def _deposit(j: int, own: np.ndarray, T: int) -> np.ndarray:
    """``(S,)`` the j-th subset of each mask of ``own``: j's bits placed, lowest first, on its
    set bits (0 where j has more bits than it)."""
    sub = np.zeros_like(own)
    rest = np.full_like(own, j)
    for b in range(T):
        has = (own >> b) & 1
        sub |= (rest & has) << b
        rest = np.where(has == 1, rest >> 1, rest)
    return np.where(rest == 0, sub, 0)


def _sharing(sets: np.ndarray, masks: np.ndarray, extra: np.ndarray) -> np.ndarray:
    """``(S, 2^T)``: for each set of stops and each tray mask M, the least failure cost of
    serving exactly M with every stop serving a non-empty part of it that it can serve
    (UNREACHABLE: none), a stop at a time."""
    S, k = sets.shape
    n_masks = extra.shape[1]
    T = n_masks.bit_length() - 1
    M = np.arange(n_masks)
    g = np.full((S, n_masks), UNREACHABLE, np.int64)
    g[:, 0] = 0
    rows = np.arange(S)[:, None]
    for i in range(k):
        own = masks[sets[:, i]]
        e = extra[sets[:, i]]  # (S, 2^T)
        nxt = np.full_like(g, UNREACHABLE)
        for j in range(1, 1 << int(np.bitwise_count(own).max())):
            sub = _deposit(j, own, T)[:, None]  # (S, 1)
            val = g[rows, M ^ sub] + e[rows, sub]
            fits = ((M & sub) == sub) & (sub != 0)
            nxt = np.where(fits, np.minimum(nxt, val), nxt)
        g = np.minimum(nxt, UNREACHABLE)
    return g


def _parts(
    stops: np.ndarray, masks: np.ndarray, extra: np.ndarray, order: tuple[int, ...]
) -> tuple[int, ...]:
    """The tray mask each stop of ``order`` serves in ``stops``' least-cost sharing."""
    k, full = len(stops), extra.shape[1] - 1
    tables = [_sharing(stops[None, :i], masks, extra)[0] for i in range(k + 1)]
    part, M = {}, full
    for i in range(k - 1, -1, -1):  # undo the last stop's part, then the one before...
        own = int(masks[stops[i]])
        sub = M & own
        while sub:  # the first of its parts that the table's value came from
            if tables[i][M ^ sub] + extra[stops[i], sub] == tables[i + 1][M]:
                break
            sub = (sub - 1) & M & own
        assert sub, "the sharing's table holds no part for this stop"
        part[int(stops[i])] = sub
        M ^= sub
    return tuple(part[c] for c in order)


def _selection(
    got: tuple[tuple[int, ...], tuple[int, ...]],
    required: list[str],
    travel: np.ndarray,
    stop_time: float,
    extra: np.ndarray,
) -> Selection:
    """An enumerated row as a :class:`Selection` (cost: route + stops + failures [s])."""
    order, parts = got
    serves = {t: c for c, part in zip(order, parts, strict=True)
              for i, t in enumerate(required) if part >> i & 1}  # fmt: skip
    nodes = [0, *(c + 2 for c in order), 1]
    route = float(sum(travel[a, b] for a, b in itertools.pairwise(nodes)))
    fails = sum(int(extra[c, p]) for c, p in zip(order, parts, strict=True)) / SCALE
    return Selection(order, serves, route + stop_time * len(order) + fails, True, 0.0)
