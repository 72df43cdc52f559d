"""The rules' verdicts on hand-made candidates with known radii and shapes."""

from __future__ import annotations

import dataclasses
import math

import pytest
import shapely
from shapely.geometry import box

from pickstop.scene.load import parse_scene
from pickstop.sequence.cover import InfeasiblePlanError
from pickstop.sequence.intersections import intersections
from pickstop.sequence.plan_model import PlanOptions
from pickstop.sequence.rules import CUT_OFF, Rule, Verdict, cut_off, judge
from pickstop.sequence.success import disc_probability


def _kept(rule, cands):
    verdicts = judge(rule, cands)
    return {tuple(sorted(c.trays)) for c, v in zip(cands, verdicts, strict=True) if v.kept}


def test_sigma_rule():
    cands = intersections({"a": box(0, 0, 2, 2), "b": box(1.8, 0, 4, 2)})
    assert _kept(Rule("sigma", 0.15), cands) == {("a",), ("b",)}  # the 0.2 m strip: r 0.1
    assert len(_kept(Rule("sigma", 0.05), cands)) == 3
    assert _kept(Rule("sigma", 2.0), cands) == set()
    strip = next(c for c in cands if len(c.trays) == 2)
    (v,) = judge(Rule("sigma", 0.15), [strip])
    assert not v.kept and "below sigma 0.150 m" in v.reason and v.predicted is None


def test_success_rule_uses_the_shape_beyond_the_disc():
    # A long 0.4 m strip: inscribed radius 0.2 m, but errors along it stay inside.
    (strip,) = intersections({"a": box(0, 0, 20, 0.4)})
    rule = Rule("success", 0.1, "gaussian", 0.8)
    (v,) = judge(rule, [strip])
    disc = disc_probability("gaussian", 0.1, strip.radius)
    assert v.kept and v.predicted is not None and v.predicted >= disc
    # A narrow strip below the target: rejected with both figures in the reason.
    (thin,) = intersections({"a": box(0, 0, 20, 0.05)})
    (w,) = judge(Rule("success", 0.1, "gaussian", 0.95), [thin])
    assert not w.kept and "below the target 95%" in w.reason
    assert disc_probability("gaussian", 0.1, thin.radius) <= w.predicted < 0.95


def test_a_radius_at_the_threshold_is_kept_whatever_the_shape():
    rule = Rule("success", 0.1, "bounded", 0.9)
    assert rule.threshold == pytest.approx(0.1 * 0.9**0.5)
    (sq,) = intersections({"a": box(0, 0, 2 * rule.threshold + 0.01, 2 * rule.threshold + 0.01)})
    assert judge(rule, [sq])[0].kept


def test_cut_off_rejects_only_kept_candidates():
    vs = [Verdict(True), Verdict(False, "too small"), Verdict(True, None, 0.97)]
    out = cut_off(vs, [False, False, True])
    assert out[0] == Verdict(False, CUT_OFF)
    assert out[1].reason == "too small"  # the rule's own reason stays
    assert out[2].kept
    with pytest.raises(ValueError, match="2 verdicts but 1"):
        cut_off(vs[:2], [True])


def test_the_success_rule_judges_each_candidate_with_its_stations_model():
    """A 0.1 m wide strip along x (inscribed radius 0.05 m): an error long along the strip
    keeps it, the same error across it or a bias off it rejects it; a tray group's own model
    applies to the candidates picking from it."""
    from pickstop.scene.positioning import ErrorDist, Positioning, Station

    (strip,) = intersections({"a": box(0, 0, 20, 0.1)})
    strip = dataclasses.replace(strip, centre=(10.0, 0.05))  # mid-strip (any centre is one)
    (square,) = intersections({"b": box(30, 0, 31, 1)})
    along = ErrorDist("gaussian", covariance=((0.04, 0.0), (0.0, 1e-6)))
    across = ErrorDist("gaussian", covariance=((1e-6, 0.0), (0.0, 0.04)))
    off = ErrorDist("gaussian", mean=(0.0, 0.06), covariance=((1e-6, 0.0), (0.0, 1e-6)))

    def verdict(dist, cand=strip):
        return judge(Rule("success", 0.1, target=0.9, positioning=Positioning(dist)), [cand])[0]

    assert strip.radius == pytest.approx(0.05)
    assert verdict(along).kept and verdict(along).predicted > 0.99
    assert not verdict(across).kept and verdict(across).predicted < 0.5
    assert not verdict(off).kept and verdict(off).predicted < 0.01
    assert verdict(ErrorDist("gaussian", mean=(0.5, 0.0))).kept  # a bias along it: inside
    # a base-frame model turns with the candidate's heading: along x at yaw pi/2 is across
    turned = dataclasses.replace(strip, yaw=math.pi / 2)
    assert not verdict(along, turned).kept
    assert verdict(dataclasses.replace(along, frame="map"), turned).kept
    group = Positioning(along, (Station("b", across, trays=frozenset({"b"})),))
    rule = Rule("success", 0.1, target=0.9, positioning=group)
    assert [v.kept for v in judge(rule, [strip, square])] == [True, True]
    narrow = dataclasses.replace(strip, trays=frozenset({"b"}))
    assert not judge(rule, [narrow])[0].kept  # the group's model, across the strip
    assert rule.threshold == pytest.approx(along.radius_for(0.9))


def test_an_isotropic_positioning_judges_as_the_rule_always_did():
    from pickstop.scene.positioning import ErrorDist, Positioning

    cands = intersections({"a": box(0, 0, 2, 2), "b": box(1.8, 0, 4, 2), "c": box(5, 0, 9, 0.3)})
    for kind in ("gaussian", "bounded"):
        plain = Rule("success", 0.12, kind, 0.9, seed=3)
        with_pos = dataclasses.replace(plain, positioning=Positioning(ErrorDist(kind, 0.12)))
        assert judge(plain, cands) == judge(with_pos, cands)
        assert plain.threshold == with_pos.threshold


def test_candidates_carry_status_and_reasons(stop_planner, paper_doc):
    scene = parse_scene(paper_doc)
    plan = stop_planner.plan(scene, PlanOptions(sigma=0.09, samples=0))
    chosen = {s.candidate for s in plan.stops}
    for c in plan.candidates:
        assert (c.status == "chosen") == (c.index in chosen)
        if c.inscribed_radius < 0.09:
            assert c.status == "rejected" and "below sigma 0.090" in c.reason
        poly = shapely.Polygon(c.polygon[0], c.polygon[1:])
        assert poly.contains(shapely.Point(c.x, c.y))


def test_success_rule_stops_meet_the_target_or_explain(stop_planner, paper_doc):
    scene = parse_scene(paper_doc)
    try:
        plan = stop_planner.plan(scene, PlanOptions(rule="success", target=0.9, samples=400))
    except InfeasiblePlanError as e:
        assert "target success 90%" in e.message
        return
    for s in plan.stops:
        assert s.success is not None and s.success.rate >= 0.9
    for c in plan.candidates:
        if c.status == "rejected" and c.reason and "predicted" in c.reason:
            assert c.predicted_success < 0.9
