"""Layout suggestions in words and ghosts: the request body, the turns field, the gain line
and the ghost boxes at the moved scene's poses."""

from __future__ import annotations

import math

import pytest

from pickstop_ui.layout_view import best, gain_text, ghosts, layout_body, parse_turns

TRAY = {"id": "tray_4", "pose": {"x": 3.7, "y": 1.5, "z": 0.725, "yaw": math.pi / 2},
        "inner_size": [0.3, 0.2], "wall_height": 0.05, "wall_thickness": 0.01,
        "floor_thickness": 0.005}  # fmt: skip


def _totals(stops, time):
    return {"totals": {"stops": stops, "time": time}, "orders": []}


def _layout(suggestions=True):
    s = {"rank": 1, "scene": {"trays": [TRAY]}, "after": _totals(2.0, 30.0),
         "gain": {"time": 5.5, "stops": 1.0},
         "moves": [{"tray": "tray_4", "from": {"x": 3.6, "y": 1.5}, "to": TRAY["pose"],
                    "turn": 90.0}]}  # fmt: skip
    worse = {**s, "rank": 2, "gain": {"time": 1.0, "stops": 0.0}}
    return {"before": _totals(3.0, 35.5), "notes": ["nothing gains"],
            "suggestions": [worse, s] if suggestions else []}  # fmt: skip


def test_the_body_asks_for_one_suggestion_of_the_movable_trays():
    body = layout_body({"trays": []}, ["tray_4"], {"samples": 0}, 0.2, [0], 3)
    assert body == {
        "scene": {"trays": []}, "options": {"samples": 0}, "step": 0.2, "turns": [0],
        "shortlist": 3, "suggestions": 1, "movable": ["tray_4"],
    }  # fmt: skip
    assert "movable" not in layout_body({}, None, {}, 0.1, [0], 12)


def test_turns_are_whole_quarter_turns():
    assert parse_turns("90, 0,90") == [0, 90]
    for bad in ("", "45", "x", "0;90"):
        with pytest.raises(ValueError, match="turns"):
            parse_turns(bad)


def test_the_gain_says_time_and_stops_before_and_after_of_the_best():
    layout = _layout()
    assert best(layout)["rank"] == 1
    text = gain_text(layout)
    assert "35.5 s → **30.0 s** (gain +5.5 s)" in text
    assert "3.00 → **2.00** (gain +1.00)" in text and "turned 90°" in text
    assert gain_text(_layout(False)) == "**No better layout found.** nothing gains"


def test_a_ghost_is_the_trays_box_where_the_suggestion_puts_it():
    (g,) = ghosts(best(_layout()))
    assert g.tray == "tray_4" and g.yaw == pytest.approx(math.pi / 2)
    assert g.size == pytest.approx((0.32, 0.22, 0.055))
    assert g.centre == pytest.approx((3.7, 1.5, 0.725 + 0.0275))
