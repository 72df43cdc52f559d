"""The planner's drawings as pure functions of a plan (no browser)."""

from __future__ import annotations

import numpy as np
import pytest

from pickstop_ui.plan_view import PREVIEW, STALE, VERIFIED, plan_drawing, playback, style_of


def test_a_verified_plan_is_drawn_with_its_regions_route_and_ghosts(plans):
    exact, _ = plans
    assert style_of(exact) is VERIFIED and style_of(exact, stale=True) is STALE
    joints = [*exact.joints, "gripper_left_finger_joint"]
    d = plan_drawing(
        exact, {"tray_1": (1, 2, 3)}, VERIFIED, joints, {"gripper_left_finger_joint": 0.04}
    )
    assert set(d.regions) == set(exact.trays) and d.regions["tray_1"][2] == (1, 2, 3)
    assert all(len(f) > 0 for _, f, _ in d.regions.values())
    assert d.route.shape[1:] == (2, 3) and len(d.route) > 2
    assert len(d.centres) == len(exact.candidates) == len(d.centre_colours)
    assert len(d.ghosts) == len(exact.stops) and all(g.cfg is not None for g in d.ghosts)
    w = exact.stops[0].witnesses[0]
    np.testing.assert_allclose(d.ghosts[0].cfg[: len(exact.joints)], w.theta)
    assert d.ghosts[0].cfg[-1] == pytest.approx((w.hand or {}).get(joints[-1], 0.04))
    assert all("(preview)" not in text for text, _ in d.labels)


def test_a_preview_is_drawn_as_one_dashed_lighter_and_without_robots(plans):
    _, preview = plans
    assert not preview.verified and style_of(preview) is PREVIEW
    d = plan_drawing(preview, {}, style_of(preview), list(preview.joints), {})
    full = plan_drawing(preview, {}, VERIFIED, list(preview.joints), {})
    assert PREVIEW.route != VERIFIED.route and PREVIEW.kept != VERIFIED.kept
    assert PREVIEW.region_opacity < VERIFIED.region_opacity and not PREVIEW.ghosts
    # Dashed: the route is cut into pieces, half of its length drawn.
    length = lambda s: float(np.linalg.norm(s[:, 1] - s[:, 0], axis=1).sum())  # noqa: E731
    assert 0.3 * length(full.route) < length(d.route) < 0.7 * length(full.route)
    assert all(g.cfg is None for g in d.ghosts)  # no witnesses in a preview
    assert d.labels and all(text.endswith("(preview)") for text, _ in d.labels)


def _travel(plan) -> list[float]:
    """A travel posture for the tests: each joint a little off every witness's value."""
    return [0.01 * (k + 1) for k in range(len(plan.joints))]


def test_playback_drives_every_leg_and_reaches_each_witness_at_its_stop(plans):
    exact, _ = plans
    steps = list(playback(exact, _travel(exact), speed=1.5, dt=0.1, reach_time=0.6))
    picks = [s for s in steps if s.what == "pick"]
    assert len(picks) == sum(len(s.witnesses) for s in exact.stops)
    for stop in exact.stops:  # each witness is reached standing on its stop
        mine = [s for s in picks if (s.x, s.y, s.yaw) == (stop.x, stop.y, stop.yaw)]
        assert [s.theta for s in mine] == [list(w.theta) for w in stop.witnesses]
        assert all(s.hold == 0.6 for s in mine)
    driving = [s for s in steps if s.what == "drive"]
    # One step per 0.15 m driven and one at each leg's start.
    route = sum(leg.length for leg in exact.legs)
    assert len(driving) == pytest.approx(route / 0.15 + len(exact.legs), abs=len(exact.legs))
    first, last = exact.legs[0].polyline[0], exact.legs[-1].polyline[-1]
    assert (driving[0].x, driving[0].y) == pytest.approx(tuple(first))
    assert np.hypot(driving[-1].x - last[0], driving[-1].y - last[1]) <= 0.15 + 1e-9
    assert (steps[-1].x, steps[-1].y) == pytest.approx(tuple(last))  # it ends at the goal


def _postures(steps) -> list[tuple[str, object]]:
    """The arm's postures in order, runs of one kind of move collapsed into one entry."""
    out: list[tuple[str, object]] = []
    for s in steps:
        if s.theta is None:
            continue
        entry = (s.what, tuple(s.theta) if s.what in ("pick", "travel", "drive") else None)
        if s.what in ("reach", "fold") and out and out[-1][0] == s.what:
            continue
        out.append(entry)
    return out


def test_playback_travels_folded_and_reaches_each_witness_from_travel_and_back(plans):
    exact, _ = plans
    travel = tuple(_travel(exact))
    steps = list(playback(exact, list(travel), dt=0.1, moves=5))
    expected: list[tuple[str, object]] = []
    for k in range(len(exact.legs)):
        expected.append(("drive", travel))  # the arm in travel as each leg starts
        if k < len(exact.stops):
            for w in exact.stops[k].witnesses:
                expected += [("reach", None), ("pick", tuple(w.theta)), ("fold", None)]
    expected.append(("travel", travel))
    assert _postures(steps) == expected
    # Between the postures the arm moves in joint space, 5 steps each way, and every fold
    # ends exactly in the travel posture; nothing but the first drive step of a leg sets it.
    folds = [k for k, s in enumerate(steps) if s.what == "fold"]
    assert len(folds) == 5 * sum(len(s.witnesses) for s in exact.stops)
    ends = [k for k in folds if k + 1 == len(steps) or steps[k + 1].what != "fold"]
    assert all(steps[k].theta == pytest.approx(travel) for k in ends)
    assert all(s.theta is None for s in steps if s.what == "drive" and s.theta != list(travel))
    w = exact.stops[0].witnesses[0]
    first = next(s for s in steps if s.what == "reach")
    assert first.theta == pytest.approx(
        [t + (x - t) / 5 for t, x in zip(travel, w.theta, strict=True)]
    )
