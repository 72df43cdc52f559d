"""The algorithm and its speed-ups agree: plans from scratch against one long-lived planner.

Random edits of the paper-like layout (trays moved along their table and turned, sigma and
the rule changed) are applied in turn to one :class:`StopPlanner`, whose caches and reuse
across layouts see them all; after each, its regions and plan are held against the pure
pipeline's (:mod:`pickstop.sequence.pure`, :mod:`pickstop.regions.pure`).
"""

from __future__ import annotations

import copy
import json
import math
from collections import Counter
from dataclasses import dataclass
from pathlib import Path
from unittest import mock

import pytest
from hypothesis import HealthCheck, given, note, settings
from hypothesis import strategies as st

from pickstop.regions import solve
from pickstop.regions.pure import PureRegions
from pickstop.regions.pure import tray_region as pure_tray_region
from pickstop.scene.load import parse_scene
from pickstop.scene.model import SceneError
from pickstop.sequence.cover import InfeasiblePlanError
from pickstop.sequence.plan_model import PlanOptions
from pickstop.sequence.pure import PureSteps
from pickstop.sequence.request import PlanRequest, plan_from_scratch
from pickstop.speedups.stop_planner import StopPlanner
from tests.utils import assert_cells_verified, unlike_cells
from tests.utils import same_document as _same

EXAMPLES = Path(__file__).parents[2] / "examples" / "scenes"
SAMPLES = 16  # Monte Carlo samples per stop: enough to exercise it, cheap
TRAYS = ["tray_1", "tray_2", "tray_3", "tray_4"]
STATS: Counter[str] = Counter()  # how the regions compared, over the whole module
SCRATCH: dict[str, dict] = {}  # layout -> its regions from scratch (a function of the layout)


@pytest.fixture(scope="module")
def paper():
    return json.loads((EXAMPLES / "paper_experiment.json").read_text())


@dataclass(frozen=True)
class _Ctx:
    """The region planner, the one stop planner for every example (its caches carry over
    from edit to edit) and the paper-like layout; a short repr for Hypothesis's reports."""

    planner: object
    wrapped: StopPlanner
    paper: dict

    def __repr__(self) -> str:
        return "ctx"


@pytest.fixture(scope="module")
def ctx(planner, paper):
    return _Ctx(planner, StopPlanner(planner), paper)


@pytest.fixture(scope="module", autouse=True)
def report():
    yield
    print(f"\nregions compared: {dict(STATS)}")


# -- edits ------------------------------------------------------------------------------------
# moves by whole cells (sometimes part of one) that keep a tray on its table most of the time
moves = st.tuples(st.just("move"), st.sampled_from(TRAYS), st.integers(-4, 4),
                  st.integers(-2, 6), st.sampled_from([0.0, 0.0, 0.0, 0.4]))  # fmt: skip
turns = st.tuples(st.just("turn"), st.sampled_from(TRAYS),
                  st.sampled_from([math.pi / 2, -math.pi / 2, 0.3]))  # fmt: skip
sigmas = st.tuples(st.just("sigma"), st.sampled_from([0.0, 0.03, 0.06, 0.1, 0.14, 0.3]))
rules = st.tuples(st.just("rule"), st.sampled_from(["sigma", "success"]),
                  st.sampled_from([0.7, 0.9]))  # fmt: skip
edits = st.lists(st.one_of(moves, turns, sigmas, rules), min_size=2, max_size=4)


def _edited(doc: dict, opts: PlanOptions, edit: tuple) -> tuple[dict, PlanOptions]:
    """The layout and options after ``edit``; a tray edit the scene refuses (the tray off
    its table or into a neighbour) leaves the layout as it was."""
    kind, *args = edit
    if kind == "sigma":
        return doc, opts.model_copy(update={"sigma": args[0]})
    if kind == "rule":
        return doc, opts.model_copy(update={"rule": args[0], "target": args[1]})
    new = copy.deepcopy(doc)
    pose = next(t for t in new["trays"] if t["id"] == args[0])["pose"]
    if kind == "move":
        res = new["base_grid"]["resolution"]
        pose["x"] += (args[1] + args[3]) * res
        pose["y"] += args[2] * res
    else:
        pose["yaw"] = pose.get("yaw", 0.0) + args[1]
    try:
        parse_scene(new)
    except SceneError:
        return doc, opts
    return new, opts


# -- the pure pipeline over given regions -------------------------------------------------------
@dataclass(frozen=True)
class _Given:
    """The pure regions, but these for the scene planned (computed once per layout)."""

    pure: PureRegions
    given: dict

    robot = property(lambda self: self.pure.robot)
    db = property(lambda self: self.pure.db)

    def regions(self, scene):
        return dict(self.given)

    def tray_region(self, scene, tray_id, yaw=None):
        return self.pure.tray_region(scene, tray_id, yaw)

    def known_regions(self, scene, pairs):
        return {}


def _pure_plan(kit, scene, opts, regions):
    """The pure stop pipeline (:class:`PureSteps`) over ``regions``."""
    steps = PureSteps(kit)
    steps.regions = _Given(steps.regions, regions)
    return _outcome(lambda: PlanRequest(steps, scene, opts).run())


def _outcome(make):
    """A plan's document without its timings, or the error's class and message."""
    try:
        return make().model_dump(exclude={"timings"})
    except InfeasiblePlanError as e:
        return (type(e).__name__, e.message)


# -- regions --------------------------------------------------------------------------------------
def _check_regions(planner, scene, scratch, wrapped) -> bool:
    """The wrapped regions hold every cell the database solves from scratch, and every cell
    scratch does not have as it is has exactly verified witnesses (the reuse across layouts:
    :mod:`pickstop.speedups.region_memo`). Returns whether they are the same regions."""
    equal = []
    for (t, yaw), s in scratch.items():
        w = wrapped[t, yaw]
        if (s.mask & ~w.mask).any():  # a grown cell may differ: those solved may not
            STATS["tray regions short of scratch's grown cells"] += 1
            with mock.patch.object(solve, "grow", lambda *a: 0):
                solved = pure_tray_region(planner.scratch(), scene, t, yaw)
            assert not (solved.mask & ~w.mask).any(), f"{t}: a solved cell is missing"
            assert (s.mask & ~w.mask).sum() <= 0.03 * s.mask.sum() + 1
        assert_cells_verified(planner, scene, w, unlike_cells(s, w))
        equal.append(s.digest == w.digest)
        STATS["tray regions equal" if equal[-1] else "tray regions differ"] += 1
    STATS["layouts with equal regions" if all(equal) else "layouts with other regions"] += 1
    return all(equal)


def _compare(planner, wrapped, scene, opts) -> None:
    """One edit's comparison (see the module)."""
    got = _outcome(lambda: wrapped.plan(scene, opts))
    STATS["refused" if isinstance(got, tuple) else "planned"] += 1
    layout = scene.model_dump_json(exclude={"sigma"})
    if layout not in SCRATCH:
        SCRATCH[layout] = PureRegions(planner.scratch()).regions(scene)
    scratch = SCRATCH[layout]
    regions = wrapped.regions.regions(scene)  # those the plan used (the layout's memo)
    same = _check_regions(planner, scene, scratch, regions)
    # Equal regions: the whole plan from scratch; else the pure stops over the same regions.
    _same(_pure_plan(planner, scene, opts, scratch if same else regions), got)


@settings(
    max_examples=10,
    deadline=None,
    suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow],
)
@given(steps=edits)
def test_random_edits_plan_as_from_scratch(ctx, steps):
    """After every edit, the long-lived planner's regions hold what scratch solves (more
    only with exactly verified witnesses) and its plan is the pure pipeline's over them."""
    doc, opts = ctx.paper, PlanOptions(samples=SAMPLES, seed=3)
    for edit in steps:
        doc, opts = _edited(doc, opts, edit)
        note(f"{edit} -> sigma {opts.sigma}, rule {opts.rule}, target {opts.target}")
        _compare(ctx.planner, ctx.wrapped, parse_scene(doc), opts)


def test_the_example_plans_from_scratch_as_a_fresh_planner(planner, paper):
    """:func:`plan_from_scratch` (regions included) gives a fresh planner's plan."""
    scene = parse_scene(paper)
    opts = PlanOptions(samples=SAMPLES)
    _same(_outcome(lambda: plan_from_scratch(planner, scene, opts)),
          _outcome(lambda: StopPlanner(planner).plan(scene, opts)))  # fmt: skip
