"""The open hand's fit: its reach past the grasp point, the pads, the offset that moves the
grasp point to the pads' inner edge."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from pickstop.frames import R_rpy, transform
from pickstop.robot.hand import TOP_DOWN_CLEARANCE, HandShape, fit_of, pad_tip


def test_a_parallel_grippers_pads_and_offset():
    # Fingers 60 mm long, the grasp point 30 mm behind their tips (at their middle).
    shape = HandShape.parallel(max_opening=0.08, finger_length=0.06, tip_offset=0.03)
    fit = fit_of(shape, np.eye(4))
    assert fit.reach == pytest.approx(0.03)
    assert fit.top_down_min == pytest.approx(0.03 + TOP_DOWN_CLEARANCE)
    assert fit.pad_tip == pytest.approx(0.03)  # the fingers' inner faces run to the tips
    assert fit.tool_offset == pytest.approx((0.03, 0.0, 0.0))
    assert fit.reach_at_pads == pytest.approx(0.0)
    # The same hand with the grasp point where the offset puts it reaches nothing past it.
    at_pads = HandShape.parallel(max_opening=0.08, finger_length=0.06, tip_offset=0.0)
    assert fit_of(at_pads, np.eye(4)).reach == pytest.approx(0.0)
    # Sideways, closing horizontally, it reaches half a finger's width below the grasp point.
    assert fit.side_below == pytest.approx(min(0.01, 0.04 + 0.01))


def test_the_offset_is_given_in_the_tool_frame():
    shape = HandShape.parallel(max_opening=0.08, finger_length=0.06, tip_offset=0.03)
    # A flange frame whose z is the approach: T_tool_tcp turns x onto z, and sits 0.1 m out.
    T_tool_tcp = transform(R_rpy(0.0, -np.pi / 2, 0.0), (0.0, 0.0, 0.1))
    fit = fit_of(shape, T_tool_tcp)
    assert fit.tool_offset == pytest.approx((0.0, 0.0, 0.13), abs=1e-9)


def test_the_pads_gap_is_measured_whatever_max_opening_says():
    shape = HandShape.parallel(max_opening=0.08, finger_length=0.06, tip_offset=0.03)
    assert fit_of(shape, np.eye(4)).pad_gap == pytest.approx(0.08, abs=1e-4)
    # max_opening given as each finger's travel (half the gap): the gap measured says so.
    wrong = replace(shape, max_opening=0.04)
    assert fit_of(wrong, np.eye(4)).pad_gap == pytest.approx(0.08, abs=1e-4)
    # A hand with nothing on one side of the closing axis has no pads.
    one_sided = replace(shape, geometries=shape.geometries[:1])
    assert pad_tip(one_sided) is None and fit_of(one_sided, np.eye(4)).tool_offset is None
