"""Expected failures against the process they describe: retries until success, then an
operator."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from pickstop.scene.load import parse_scene
from pickstop.scene.model import FailureModel
from pickstop.sequence.failure import (
    FailureCosts,
    expected_retries,
    failure_time,
    operator_probability,
    stop_failures,
)
from pickstop.sequence.plan_model import PlanOptions


def simulate(p: float, costs: FailureCosts, runs: int, rng: np.random.Generator):
    """Per run: re-docks, operator called, extra time [s], by drawing each landing."""
    retries = np.zeros(runs)
    operator = np.zeros(runs, bool)
    extra = np.zeros(runs)
    ok = rng.random(runs) < p
    for _ in range(costs.retries):
        again = ~ok
        retries += again
        extra += again * costs.retry_time
        ok |= again & (rng.random(runs) < p)
    operator = ~ok
    extra += operator * costs.operator_time
    return retries, operator, extra


@settings(max_examples=30, deadline=None)
@given(
    p=st.floats(0.0, 1.0),
    retries=st.integers(0, 4),
    retry_time=st.floats(0.0, 60.0),
    operator_time=st.floats(0.0, 900.0),
)
def test_expectations_match_the_simulated_process(p, retries, retry_time, operator_time):
    costs = FailureCosts(retry_time, retries, operator_time)
    r, o, t = simulate(p, costs, 40_000, np.random.default_rng(7))
    f = stop_failures(p, costs)

    # 40,000 runs: five standard errors of each mean, and three runs' worth of the largest
    # value where events are too rare for the runs to show their spread
    def near(xs, most):
        return pytest.approx(xs.mean(), abs=5 * xs.std() / 200 + 3 * most / len(xs) + 1e-9)

    assert f.retries == near(r, retries)
    assert f.operator == near(o, 1.0)
    assert f.time == near(t, retries * retry_time + operator_time)


def test_certain_and_hopeless_stops():
    costs = FailureCosts(15.0, 2, 300.0)
    assert failure_time(1.0, costs) == 0.0
    assert failure_time(0.0, costs) == pytest.approx(2 * 15.0 + 300.0)
    assert expected_retries(0.0, 2) == 2 and operator_probability(0.0, 2) == 1.0
    # a 77% stop: 0.23 + 0.23^2 re-docks, 0.23^3 operator calls
    assert failure_time(0.77, costs) == pytest.approx(15 * (0.23 + 0.23**2) + 300 * 0.23**3)


def test_vectorised_over_rates_and_monotone():
    ps = np.linspace(0, 1, 101)
    t = failure_time(ps, FailureCosts(15.0, 2, 300.0))
    assert t.shape == ps.shape and np.all(np.diff(t) <= 0)


def test_costs_of_the_scene_model_defaults():
    costs = FailureCosts.of(FailureModel())
    assert costs == FailureCosts(15.0, 2, 300.0)


def test_plan_reports_expected_time_with_failures_beside_the_predicted(paper_plan):
    from pickstop.sequence.failure import FailureCosts, failure_time

    scene, plan = paper_plan
    costs = FailureCosts.of(scene.failure)
    assert plan.parameters.failure == scene.failure
    t = plan.totals.time
    extra = 0.0
    for s in plan.stops:
        f = s.failures
        assert f is not None and f.source == "monte_carlo" and f.success == s.success.rate
        assert f.time == pytest.approx(float(failure_time(s.success.rate, costs)))
        extra += f.time
    assert t.failures == pytest.approx(extra) and t.expected == pytest.approx(t.total + extra)
    assert t.expected >= t.total
    assert plan.totals.retries == pytest.approx(sum(s.failures.retries for s in plan.stops))


def test_a_dearer_failure_model_raises_only_the_expected_time(stop_planner, paper_doc):
    free = {"relocalise_time": 0, "redock_time": 0, "operator_time": 0}
    dear = {"relocalise_time": 20, "redock_time": 40, "retries": 1, "operator_time": 900}
    plans = [
        stop_planner.plan(parse_scene({**paper_doc, "failure": f}), PlanOptions(samples=300))
        for f in (free, dear)
    ]
    assert plans[0].totals.time.total == plans[1].totals.time.total
    assert plans[0].totals.time.expected == pytest.approx(plans[0].totals.time.total)
    assert plans[1].totals.time.expected == pytest.approx(
        plans[1].totals.time.total
        + sum(60 * (1 - s.success.rate) + 900 * (1 - s.success.rate) ** 2 for s in plans[1].stops)
    )
