"""Time model arithmetic."""

from __future__ import annotations

import math

import numpy as np
import pytest

from pickstop.sequence.timing import leg_time, plan_time


def test_long_leg_reaches_top_speed():
    # v = 0.5, a = 0.5: 0.25 m to speed up, 0.25 m to stop; 4 m -> 3.5 m cruising at 0.5.
    assert leg_time(4.0, 0.5, 0.5) == pytest.approx(1.0 + 7.0 + 1.0)


def test_short_leg_is_triangular():
    # 0.2 m < v^2 / a = 0.5 m: t = 2 sqrt(L / a)
    assert leg_time(0.2, 1.0, 2.0) == pytest.approx(2 * math.sqrt(0.1))


def test_profile_is_continuous_and_increasing():
    L = np.linspace(0, 3, 301)
    t = leg_time(L, 0.6, 0.4)
    assert t[0] == 0 and (np.diff(t) > 0).all()
    knee = 0.6**2 / 0.4
    assert leg_time(knee - 1e-9, 0.6, 0.4) == pytest.approx(leg_time(knee, 0.6, 0.4))


def test_plan_time_adds_stops_and_picks():
    b = plan_time([4.0, 4.0], n_stops=1, n_parts=3, v=0.5, a=0.5, stop_time=8, pick_time=6)
    assert b.travel == pytest.approx(18.0)
    assert b.total == pytest.approx(18 + 8 + 18)


def test_a_leg_halts_at_each_end_of_its_docking_segments():
    from pickstop.sequence.timing import pieces_time, rest_pieces

    line = [(0, 0), (3, 0), (3, 0.4), (3, 0.8), (6, 0.8)]
    assert rest_pieces(line, []) == pytest.approx([6.8])
    # Docked at the second and third segments (one yaw): halts at (3, 0) and (3, 0.8).
    assert rest_pieces(line, [None, 1.5, 1.5, None]) == pytest.approx([3.0, 0.4, 0.4, 3.0])
    assert rest_pieces(line, [None, None, None, 0.0]) == pytest.approx([3.8, 3.0])
    t = pieces_time(rest_pieces(line, [None, 1.5, None, None]), 0.5, 0.5)
    assert t == pytest.approx(leg_time(3.0, 0.5, 0.5) + leg_time(0.4, 0.5, 0.5)
                              + leg_time(3.4, 0.5, 0.5))  # fmt: skip
    assert t > leg_time(6.8, 0.5, 0.5)
    with pytest.raises(ValueError, match="2 segment yaws for 5 waypoints"):
        rest_pieces(line, [None, 1.0])
    # plan_time takes a leg as its pieces
    b = plan_time([[3.0, 0.4], 4.0], n_stops=1, n_parts=0, v=0.5, a=0.5, stop_time=8, pick_time=6)
    assert b.travel == pytest.approx(leg_time(3.0, 0.5, 0.5) + leg_time(0.4, 0.5, 0.5) + 9.0)
