"""Layout suggestions: where to move a few trays so that the mix runs in the least time.

1. Slots for each movable tray (:mod:`pickstop.layout.slots`); the region of each tray once
   per turn (where it stands, or at the turn's nearest free slot).
2. Predict (:mod:`pickstop.layout.predict`): every slot of every movable tray with the others
   where they stand, then a beam of the best layouts improved one tray at a time, a few
   rounds. The objective: orders without a plan, then the weighted mean time, then stops.
3. Rank: the best predicted layouts planned exactly (every order, no Monte Carlo).
4. Verify: the best that beat the layout as it is, planned exactly again from scratch with
   the request's options (:mod:`pickstop.layout.verify`); their figures are the suggestion's.
"""

from __future__ import annotations

import json
import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field

from pickstop.errors import InputError
from pickstop.layout import model as lm
from pickstop.layout.predict import Predictor
from pickstop.layout.slots import Slot, home_slot, slots_meet, tray_slots
from pickstop.layout.verify import Evaluator
from pickstop.scene.load import parse_scene
from pickstop.scene.model import Order, Scene, SceneError
from pickstop.sequence.mix import MixPlans, mix_document, mix_trays
from pickstop.sequence.plan_model import PlanOptions
from pickstop.speedups.region_planner import RegionPlanner

#: (fraction of the search done, what it is doing)
Progress = Callable[[float, str], None]
Key = tuple[int, ...]  # a layout: the slot index of each movable tray (0: where it stands)
Objective = tuple[float, float, float]  # orders without a plan, weighted time [s], stops
MAX_MOVABLE = 6  # trays one search may move


@dataclass(frozen=True)
class SearchSettings:
    """How widely to search: slot lattice ``step`` [m] (whole grid cells), ``turns`` [deg],
    how many suggestions, how many layouts are planned exactly to rank them (``shortlist``),
    and the beam and rounds of the search over several trays."""

    step: float = 0.1
    turns: tuple[int, ...] = (0, 90, 180, 270)
    suggestions: int = 3
    shortlist: int = 12
    beam: int = 4
    rounds: int = 3


@dataclass
class Space:
    """The layouts of a search: each movable tray's slots and the predicted objective of
    every layout tried (None: two moved trays would meet)."""

    scene: Scene
    orders: list[Order]
    movable: list[str]
    slots: dict[str, list[Slot]]
    predictor: Predictor
    tried: dict[Key, Objective | None] = field(default_factory=dict)
    _homes: dict[str, Slot] = field(default_factory=dict)
    _meets: dict[tuple[Slot, Slot], bool] = field(default_factory=dict)

    @property
    def home(self) -> Key:
        return (0,) * len(self.movable)

    def layout(self, key: Key) -> list[Slot]:
        return [self.slots[t][k] for t, k in zip(self.movable, key, strict=True)]

    def predict(self, key: Key) -> Objective | None:
        if key not in self.tried:
            self.tried[key] = None if self._clash(key) else self._objective(key)
        return self.tried[key]

    def _clash(self, key: Key) -> bool:
        placed = self.layout(key)
        for i, a in enumerate(placed):
            for b in placed[i + 1 :]:
                if (a, b) not in self._meets:
                    ta, tb = self.scene.tray(a.tray), self.scene.tray(b.tray)
                    self._meets[a, b] = slots_meet(a, b, ta, tb)
                if self._meets[a, b]:
                    return True
        return False

    def _objective(self, key: Key) -> Objective:
        at = {s.tray: s for s in self.layout(key)}
        failed, time_, stops, weight = 0, 0.0, 0.0, 0.0
        for o in self.orders:
            placed = tuple(at.get(t) or self._home(t) for t in self.scene.order_trays(o))
            n, t = self.predictor.order_cost(placed)
            if math.isinf(t):
                failed += 1
            else:
                time_, stops, weight = time_ + o.weight * t, stops + o.weight * n, weight + o.weight
        if not weight:
            return (failed, math.inf, math.inf)
        return (failed, time_ / weight, stops / weight)

    def _home(self, tray_id: str) -> Slot:
        if tray_id not in self._homes:
            self._homes[tray_id] = home_slot(self.scene, tray_id)
        return self._homes[tray_id]

    def ranked(self) -> list[tuple[Key, Objective]]:
        """Every layout tried whose trays do not meet, best first (ties: fewest moves)."""
        valid = [(k, v) for k, v in self.tried.items() if v is not None]
        return sorted(valid, key=lambda kv: (kv[1], sum(i != 0 for i in kv[0]), kv[0]))

    def moved_scene(self, key: Key) -> Scene | None:
        """The scene with the trays in the layout's slots, checked (None if invalid)."""
        at = {s.tray: s for s in self.layout(key)}
        trays = [at[t.id].placed(t) if t.id in at else t for t in self.scene.trays]
        doc = json.loads(self.scene.model_copy(update={"trays": trays}).model_dump_json())
        try:
            return parse_scene(doc)
        except SceneError:
            return None


def descend(space: Space, settings: SearchSettings, progress: Progress | None = None) -> None:
    """Fill ``space.tried``: from the layout as it is, each round moves one tray of each of
    the ``beam`` best layouts to every one of its slots; stops when the beam holds."""
    beam = [space.home]
    space.predict(space.home)
    for r in range(settings.rounds if len(space.movable) > 1 else 1):
        for n, key in enumerate(beam):
            for i, t in enumerate(space.movable):
                for j in range(len(space.slots[t])):
                    space.predict((*key[:i], j, *key[i + 1 :]))
            if progress is not None:
                progress((r + (n + 1) / len(beam)) / settings.rounds, "predicting layouts")
        best = [k for k, _ in space.ranked()[: settings.beam]]
        if best == beam:
            break
        beam = best


def build_space(
    rp: RegionPlanner,
    scene: Scene,
    orders: list[Order],
    movable: list[str],
    options: PlanOptions,
    settings: SearchSettings,
) -> Space:
    """Slots of the movable trays and the predictor (each tray's region once per turn)."""
    res = scene.base_grid.resolution
    step = max(1, round(settings.step / res)) * res  # whole cells: regions carry exactly
    slots = {t: tray_slots(scene, t, movable, step, settings.turns) for t in movable}
    refs: dict[tuple[str, int], Slot] = {}
    for t, mine in slots.items():
        for turn in {s.turn for s in mine} - {0}:
            refs[t, turn] = _free_slot(scene, t, [s for s in mine if s.turn == turn], movable)
    trays = list(dict.fromkeys([*mix_trays(scene, orders), *movable]))
    sigma = scene.sigma if options.sigma is None else options.sigma
    fewest = options.objective == "stops"
    predictor = Predictor.of(rp, scene, trays, refs, sigma, fewest)
    return Space(scene, orders, movable, slots, predictor)


def _free_slot(scene: Scene, tray_id: str, mine: list[Slot], movable: list[str]) -> Slot:
    """The first of ``mine`` (nearest first) clear of the other movable trays where they
    stand: where the turned tray's region is computed."""
    others = [(home_slot(scene, t), scene.tray(t)) for t in movable if t != tray_id]
    tray = scene.tray(tray_id)
    for s in mine:
        if not any(slots_meet(s, h, tray, t) for h, t in others):
            return s
    return mine[0]


def check_request(scene: Scene, orders: list[Order], movable: list[str]) -> None:
    """Movable trays exist, are few enough, and some order needs each (else its place
    changes nothing)."""
    if not movable:
        raise InputError("movable: give at least one tray to move", field="movable")
    if len(movable) > MAX_MOVABLE:
        raise InputError(f"movable: {len(movable)} trays exceed the limit of {MAX_MOVABLE}",
                         field="movable")  # fmt: skip
    needed = set(mix_trays(scene, orders))
    for i, t in enumerate(movable):
        if t not in {x.id for x in scene.trays}:
            raise InputError(f"movable.{i}: no tray {t!r} in the scene", field=f"movable.{i}")
        if t not in needed:
            raise InputError(f"movable.{i}: no order needs tray {t!r}", field=f"movable.{i}")


def suggest(
    rp: RegionPlanner,
    evaluator: Evaluator,
    scene: Scene,
    orders: list[Order],
    movable: list[str],
    options: PlanOptions,
    settings: SearchSettings | None = None,
    progress: Progress | None = None,
) -> lm.Layout:
    """Suggested layouts (see the module), best first, each verified."""
    settings = settings or SearchSettings()
    check_request(scene, orders, movable)
    clock = _Clock(progress)
    space = build_space(rp, scene, orders, movable, options, settings)
    clock.lap("regions", 0.15, "slots and regions")
    return search(space, evaluator, options, settings, clock)


def search(
    space: Space,
    evaluator: Evaluator,
    options: PlanOptions,
    settings: SearchSettings,
    clock: _Clock | Progress | None = None,
) -> lm.Layout:
    """Steps 2 to 4 of the module over ``space`` (its slots as they are: a search may be
    narrowed to some of them)."""
    clock = clock if isinstance(clock, _Clock) else _Clock(clock)
    descend(space, settings, lambda f, msg: clock.say(0.15 + 0.25 * f, msg))
    clock.lap("predict", 0.4, "planning the best layouts exactly")
    exact = _rank(space, evaluator, settings.shortlist, clock)
    clock.lap("plan", 0.6, "verifying the best layouts")
    return _verify(space, evaluator, exact, options, settings, clock)


def _rank(
    space: Space, evaluator: Evaluator, shortlist: int, clock: _Clock
) -> list[tuple[Key, Scene, Objective, Objective]]:
    """The layout as it is and the ``shortlist`` best predicted, planned exactly (no Monte
    Carlo): (key, moved scene, exact objective, predicted objective), best first."""
    keys = [space.home]
    for key, _ in space.ranked():
        if len(keys) > shortlist:
            break
        if key != space.home:
            keys.append(key)
    scenes = {k: s for k in keys if (s := space.moved_scene(k)) is not None}
    plans = evaluator.rank(list(scenes.values()))
    out = []
    for (key, scene), mix in zip(scenes.items(), plans, strict=True):
        predicted = space.tried[key]
        assert predicted is not None
        out.append((key, scene, objective(mix), predicted))
    clock.count["planned"] = len(out)
    return sorted(out, key=lambda x: (x[2], sum(i != 0 for i in x[0])))


APART = 0.25  # [m] suggestions differ by more than this in some tray's place (or its turn)


def _distinct(
    space: Space, layouts: list[tuple[Key, Scene, Objective, Objective]]
) -> list[tuple[Key, Scene, Objective, Objective]]:
    """``layouts`` (best first) without those that put every tray within :data:`APART` of
    where a better one puts it, turned the same: a few different suggestions, not one twice."""
    out: list[tuple[Key, Scene, Objective, Objective]] = []

    def near(a: Slot, b: Slot) -> bool:
        return a.turn == b.turn and math.hypot(a.x - b.x, a.y - b.y) <= APART

    for x in layouts:
        mine = space.layout(x[0])
        if not any(all(map(near, mine, space.layout(y[0]))) for y in out):
            out.append(x)
    return out


def objective(mix: MixPlans) -> Objective:
    """Orders without a plan, weighted mean time [s], weighted mean stops."""
    t = mix_document(mix).totals
    return (float(len(t.failed)), t.time if t.time is not None else math.inf, t.stops or 0.0)


def _verify(
    space: Space,
    evaluator: Evaluator,
    exact: list[tuple[Key, Scene, Objective, Objective]],
    options: PlanOptions,
    settings: SearchSettings,
    clock: _Clock,
) -> lm.Layout:
    """The suggestions: the best exactly planned layouts that beat the layout as it is,
    verified, ranked by their verified figures."""
    home = next(x for x in exact if x[0] == space.home)
    better = _distinct(space, [x for x in exact if x[0] != space.home and x[2] < home[2]])
    better = better[: settings.suggestions]
    before = evaluator.verify([home[1]])[0]
    verified: list[tuple[MixPlans, tuple[Key, Scene, Objective, Objective]]] = []
    for n, x in enumerate(better):
        mix = evaluator.verify([x[1]])[0]
        verified.append((mix, x))
        if objective(mix) < objective(before):
            clock.first()
        clock.say(0.6 + 0.4 * (n + 1) / len(better), "verifying the best layouts")
    clock.count["verified"] = len(verified) + 1
    keep = [(m, x) for m, x in verified if objective(m) < objective(before)]
    keep.sort(key=lambda mx: objective(mx[0]))
    suggestions = [_suggestion(space, n + 1, m, x, before) for n, (m, x) in enumerate(keep)]
    clock.lap("verify", 1.0, "done")
    notes = [] if suggestions else [
        f"no layout found that beats the one as it is: {len(space.tried)} layouts predicted, "
        f"{clock.count.get('planned', 0)} planned exactly, {len(verified)} verified"
    ]  # fmt: skip
    return lm.Layout(
        scene=space.scene.name,
        options=options,
        orders=[o.id for o in space.orders],
        movable=space.movable,
        before=_figures(before),
        suggestions=suggestions,
        notes=notes,
        search=lm.SearchStats(
            slots={t: len(s) for t, s in space.slots.items()},
            predicted=len(space.tried),
            planned=clock.count.get("planned", 0),
            verified=clock.count["verified"],
            seconds=clock.seconds,
        ),
    )


def _figures(mix: MixPlans) -> lm.Figures:
    doc = mix_document(mix)
    return lm.Figures(totals=doc.totals, orders=doc.orders)


def _suggestion(
    space: Space,
    rank: int,
    mix: MixPlans,
    x: tuple[Key, Scene, Objective, Objective],
    before: MixPlans,
) -> lm.Suggestion:
    key, scene, ranked, predicted = x
    after, was = _figures(mix), _figures(before)
    moves = []
    for slot in space.layout(key):
        old = space.scene.tray(slot.tray).pose
        if slot.pose != old:
            moves.append(lm.Move(tray=slot.tray, was=old, to=slot.pose, turn=slot.turn))
    a, b = after.totals, was.totals

    def minus(p: float | None, q: float | None) -> float | None:
        return None if p is None or q is None else p - q

    return lm.Suggestion(
        rank=rank,
        moves=moves,
        scene=json.loads(scene.model_dump_json()),
        after=after,
        gain=lm.Gain(
            time=minus(b.time, a.time),
            stops=minus(b.stops, a.stops),
            success=minus(a.success, b.success),
        ),
        predicted={"stops": predicted[2], "time": predicted[1]},
        ranked={"stops": ranked[2], "time": ranked[1]},
    )


class _Clock:
    """Stage times [s], counts and progress of one search."""

    def __init__(self, progress: Progress | None) -> None:
        self.progress = progress
        self.t0 = self.last = time.perf_counter()
        self.seconds: dict[str, float] = {}
        self.count: dict[str, int] = {}

    def say(self, fraction: float, message: str) -> None:
        if self.progress is not None:
            self.progress(min(max(fraction, 0.0), 1.0), message)

    def lap(self, name: str, fraction: float, message: str) -> None:
        now = time.perf_counter()
        self.seconds[name] = now - self.last
        self.seconds["total"] = now - self.t0
        self.last = now
        self.say(fraction, message)

    def first(self) -> None:
        self.seconds.setdefault("first", time.perf_counter() - self.t0)


def exhaustive(space: Space, evaluator: Evaluator, batch: int = 16) -> list[tuple[Key, Objective]]:
    """Every layout of ``space``'s slots whose trays do not meet, planned exactly (every
    order, no Monte Carlo), best first: the true optimum of a small instance, to measure a
    search's gap."""
    import itertools

    keys = [k for k in itertools.product(*(range(len(space.slots[t])) for t in space.movable))
            if space.predict(k) is not None]  # fmt: skip
    out: list[tuple[Key, Objective]] = []
    for i in range(0, len(keys), batch):
        chunk = [(k, s) for k in keys[i : i + batch] if (s := space.moved_scene(k)) is not None]
        mixes = evaluator.rank([s for _, s in chunk])
        out += [(k, objective(m)) for (k, _), m in zip(chunk, mixes, strict=True)]
    return sorted(out, key=lambda kv: (kv[1], sum(i != 0 for i in kv[0]), kv[0]))
