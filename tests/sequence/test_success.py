"""Error models and the Monte Carlo against analytic answers."""

from __future__ import annotations

import math

import numpy as np
import pytest

from pickstop.scene.load import parse_scene
from pickstop.sequence.plan_model import PlanOptions
from pickstop.sequence.success import (
    YAW_LATTICE,
    Rate,
    combined,
    disc_probability,
    monte_carlo,
    radius_for,
    sample_errors,
)


def test_gaussian_mean_error_magnitude_is_sigma():
    dxy, dyaw = sample_errors("gaussian", 0.1, 0.0, 200_000, np.random.default_rng(1))
    assert np.linalg.norm(dxy, axis=1).mean() == pytest.approx(0.1, rel=0.01)
    assert not dyaw.any()


def test_bounded_is_uniform_in_the_disc():
    dxy, _ = sample_errors("bounded", 0.2, 0.0, 100_000, np.random.default_rng(2))
    r = np.linalg.norm(dxy, axis=1)
    assert r.max() <= 0.2
    assert (r <= 0.1).mean() == pytest.approx(0.25, abs=0.01)  # area fraction


def test_yaw_errors_lie_on_the_lattice():
    _, dyaw = sample_errors("gaussian", 0.1, math.radians(2), 5000, np.random.default_rng(3))
    assert dyaw.std() == pytest.approx(math.radians(2), rel=0.05)
    k = dyaw / YAW_LATTICE
    assert np.allclose(k, np.round(k))


@pytest.mark.parametrize("kind", ["gaussian", "bounded"])
@pytest.mark.parametrize("target", [0.5, 0.9, 0.95, 0.99])
def test_radius_for_inverts_disc_probability(kind, target):
    r = radius_for(kind, 0.1, target)
    assert disc_probability(kind, 0.1, r) == pytest.approx(target)


def test_paper_rule_under_gaussian_guarantees_54_percent():
    assert disc_probability("gaussian", 0.1, 0.1) == pytest.approx(1 - math.exp(-math.pi / 4))
    assert radius_for("gaussian", 0.1, 0.95) == pytest.approx(0.1953, abs=1e-4)


@pytest.mark.parametrize("kind", ["gaussian", "bounded"])
@pytest.mark.parametrize("offset", [0.0, 0.05])
def test_monte_carlo_matches_a_disc_region(kind, offset):
    """Region: a disc of radius R around (1 + offset, 2). Centred: the analytic answer is
    disc_probability; off-centre it is checked by numerical integration."""
    R, sigma, centre = 0.08, 0.1, (1.0, 2.0)

    def inside(xy, yaw):
        return np.hypot(xy[:, 0] - centre[0] - offset, xy[:, 1] - centre[1]) <= R

    n = 40_000
    rate = monte_carlo(inside, centre, 0.0, kind, sigma, 0.0, n, np.random.default_rng(4))
    if offset == 0.0:
        expected = disc_probability(kind, sigma, R)
    else:  # integrate the error density over the shifted disc on a fine grid
        g = np.linspace(-0.3, 0.3, 1201)
        X, Y = np.meshgrid(g, g)
        if kind == "gaussian":
            s = sigma * math.sqrt(2 / math.pi)
            dens = np.exp(-(X**2 + Y**2) / (2 * s * s)) / (2 * math.pi * s * s)
        else:
            dens = (np.hypot(X, Y) <= sigma) / (math.pi * sigma**2)
        mask = np.hypot(X - offset, Y) <= R
        expected = float((dens * mask).sum() * (g[1] - g[0]) ** 2)
    lo, hi = rate.interval
    assert lo <= expected <= hi
    assert rate.rate == pytest.approx(expected, abs=0.01)


def test_yaw_error_is_judged_at_each_sampled_yaw():
    seen = []

    def only_small_yaw(xy, yaw):
        seen.append(yaw)
        return np.full(len(xy), abs(yaw) <= math.radians(1.0) + 1e-12)

    rate = monte_carlo(
        only_small_yaw, (0, 0), 0.0, "gaussian", 0.1, math.radians(1.0), 20_000,
        np.random.default_rng(5),
    )  # fmt: skip
    assert len(seen) > 5  # one call per distinct yaw on the lattice
    # On the 0.25 deg lattice, |yaw| <= 1 deg holds for |N(0, 1 deg)| < 1.125 deg.
    assert rate.rate == pytest.approx(math.erf(1.125 / math.sqrt(2)), abs=0.01)


def test_wilson_interval_and_plan_product():
    r = Rate(1000, 950)
    lo, hi = r.interval
    assert lo == pytest.approx(0.9346, abs=1e-3) and hi == pytest.approx(0.9626, abs=1e-3)
    wide = r.wilson(4.0)  # 99.99%: the same centre, wider
    assert wide[0] < lo and wide[1] > hi and r.wilson(1.959963984540054) == (lo, hi)
    assert Rate(100, 100).interval[1] == 1.0 and Rate(100, 0).interval[0] == pytest.approx(
        0.0, abs=1e-12
    )
    for n in (1, 7, 100, 300, 1000):  # the interval holds the observed rate at both ends
        for k in (0, n):
            lo, hi = Rate(n, k).interval
            assert lo <= k / n <= hi
    p, (plo, phi) = combined([Rate(100, 90), Rate(100, 50)])
    assert p == pytest.approx(0.45) and plo < p < phi


@pytest.mark.parametrize("sigma", [1e-300, 5e-324])
def test_a_sigma_too_small_to_square_still_gives_a_probability(sigma):
    """A subnormal sigma squares to 0: the disc bound is taken from ratios, never from it."""
    for kind in ("gaussian", "bounded"):
        assert disc_probability(kind, sigma, 0.1) == 1.0
        assert disc_probability(kind, sigma, 0.0) == 0.0
        assert math.isfinite(radius_for(kind, sigma, 0.95))


def test_bounded_error_with_the_paper_rule_always_succeeds(stop_planner, paper_doc):
    paper_doc["error_model"] = {"kind": "bounded"}
    paper_doc["sigma"] = 0.05
    plan = stop_planner.plan(parse_scene(paper_doc), PlanOptions(samples=300))
    # A disc of radius sigma inside a region of verified cells: misses can only come from
    # the gaps between cell centres, which the exact test at each sample judges.
    assert all(s.success.rate >= 0.97 for s in plan.stops)


def test_a_stations_own_error_model_gives_its_stop_its_success_rate(
    stop_planner, paper_plan, paper_doc
):
    """A tray group whose base lands 0.5 m behind its stop (tightly; away from the table):
    that stop's Monte Carlo uses it and falls; every other stop keeps its rate, drawn as
    before."""
    _, plain = paper_plan
    group = plain.stops[0].trays
    paper_doc["error_model"] = {
        **paper_doc.get("error_model", {}),
        "stations": [{"name": "backs-off", "trays": group, "mean": [-0.5, 0.0],
                      "covariance": [[1e-6, 0.0], [0.0, 1e-6]]}],
    }  # fmt: skip
    plan = stop_planner.plan(parse_scene(paper_doc), PlanOptions(samples=300))
    assert [s.trays for s in plan.stops] == [s.trays for s in plain.stops]
    for s, p in zip(plan.stops, plain.stops, strict=True):
        if s.trays == group:
            assert s.error_model == "backs-off" and s.success.rate < 0.05 < p.success.rate
        else:
            assert s.error_model is None and s.success == p.success
