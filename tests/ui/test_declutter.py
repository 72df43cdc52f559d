"""Labels that never overlap: greedy by priority, boxes from the text's length."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from pickstop_ui.declutter import Label, label_box, visible


def _overlap(a, b) -> bool:
    return a[0] < b[2] and b[0] < a[2] and a[1] < b[3] and b[1] < a[3]


def test_of_two_overlapping_labels_the_higher_priority_one_stays():
    labels = [Label("a", "tray_01", (0, 0, 0), 1.0), Label("b", "tray_02", (0, 0, 0), 2.0),
              Label("c", "far away", (0, 0, 0), 0.0)]  # fmt: skip
    px = np.array([[100.0, 100.0], [110.0, 102.0], [400.0, 300.0]])
    assert visible(labels, px, np.array([True, True, True]), 800) == {"a": False, "b": True,
                                                                     "c": True}  # fmt: skip
    behind = visible(labels, px, np.array([True, False, True]), 800)
    assert behind == {"a": True, "b": False, "c": True}


def test_longer_text_makes_a_wider_box_and_a_taller_view_a_larger_font():
    a, b = label_box((0, 0), "ab", 800), label_box((0, 0), "abcdef", 800)
    assert b[2] - b[0] > a[2] - a[0] and a[3] == 0.0 and a[1] < 0
    big = label_box((0, 0), "ab", 1600)
    assert big[3] - big[1] > a[3] - a[1]


@settings(max_examples=100, deadline=None)
@given(st.lists(st.tuples(st.floats(0, 1200), st.floats(0, 800), st.text(min_size=1,
                                                                      max_size=20),
                          st.floats(-3, 3)), min_size=1, max_size=30))  # fmt: skip
def test_the_labels_shown_never_overlap(spec):
    labels = [Label(str(k), t, (0, 0, 0), p) for k, (_, _, t, p) in enumerate(spec)]
    px = np.array([[x, y] for x, y, _, _ in spec])
    shown = visible(labels, px, np.ones(len(spec), bool), 800)
    boxes = [label_box(tuple(px[k]), labels[k].text, 800) for k in range(len(spec))
             if shown[str(k)]]  # fmt: skip
    assert boxes, "the highest priority label is always shown"
    for i, a in enumerate(boxes):
        for b in boxes[i + 1 :]:
            assert not _overlap(a, b)


def test_a_point_ahead_of_the_camera_lands_at_the_centre_and_one_behind_is_not_in_front():
    from pickstop_ui.declutter import quat_matrix, screen_points

    # OpenCV frame looking along world +x: z_cam = +x, x_cam = -y, y_cam = -z.
    R = np.array([[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])
    w = np.sqrt(1 + np.trace(R)) / 2
    wxyz = (w, (R[2, 1] - R[1, 2]) / (4 * w), (R[0, 2] - R[2, 0]) / (4 * w),
            (R[1, 0] - R[0, 1]) / (4 * w))  # fmt: skip
    assert np.allclose(quat_matrix(wxyz), R)
    pts = np.array([[5.0, 0.0, 0.0], [5.0, -1.0, 1.0], [-5.0, 0.0, 0.0]])
    px, ahead = screen_points((0, 0, 0), wxyz, np.pi / 2, (800, 600), pts)
    assert np.allclose(px[0], (400, 300)) and list(ahead) == [True, True, False]
    assert px[1][0] > 400 and px[1][1] < 300  # -y is right, +z is up on screen
