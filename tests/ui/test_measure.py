"""The measure tool's words: the distance, its floor part and components."""

from __future__ import annotations

from pickstop_ui.measure import distance_text


def test_the_distance_text_gives_the_length_and_its_parts():
    text = distance_text((0.0, 0.0, 0.0), (3.0, 4.0, 12.0))
    assert "**Distance: 13.000 m**" in text and "on the floor 5.000 m" in text
    assert "Δx +3.000, Δy +4.000, Δz +12.000 m" in text
