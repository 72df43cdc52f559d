"""The top-view drawing: well-formed SVG with every tray named once, names that do not
overlap, a scale bar of a round length."""

from __future__ import annotations

import json
import math
import re
import xml.etree.ElementTree as ET
from pathlib import Path

from hypothesis import given
from hypothesis import strategies as st

from pickstop.report.drawing import Frame, _tray_labels, nice_length, top_view_svg

SCENES = Path(__file__).parents[2] / "examples" / "scenes"
SVG = "{http://www.w3.org/2000/svg}"


def test_the_drawing_is_svg_with_every_tray_stop_and_circle(paper_plan, paper_scene):
    root = ET.fromstring(top_view_svg(paper_plan, paper_scene))
    texts = [t.text for t in root.iter(f"{SVG}text")]
    for tray in paper_scene["trays"]:
        assert texts.count(tray.get("name") or tray["id"]) == 1
    for k in range(len(paper_plan.stops)):
        assert str(k + 1) in texts
    assert "start" in texts and "goal" in texts and any(t.endswith(" m") for t in texts)
    titles = [t.text for t in root.iter(f"{SVG}title")]
    assert sum("candidate" in t for t in titles) == len(paper_plan.candidates)
    assert len(list(root.iter(f"{SVG}polyline"))) == 1  # the route


def _boxes(svg_texts: list[str]) -> list[tuple[float, float, float, float]]:
    out = []
    for s in svg_texts:
        x, y = (float(v) for v in re.search(r"x='([\d.-]+)' y='([\d.-]+)'", s).groups())
        w = 6.3 * len(re.search(r">([^<]*)</text>", s).group(1)) + 4
        out.append((x - w / 2, y - 10, x + w / 2, y + 3))
    return out


def test_tray_names_never_overlap_in_the_factory_cell():
    scene = json.loads((SCENES / "factory_cell.json").read_text())
    (x0, _), (x1, y1) = scene["floor"]["min"], scene["floor"]["max"]
    boxes = _boxes(_tray_labels(Frame(x0, y1, 860 / (x1 - x0)), scene))
    assert len(boxes) == len(scene["trays"])
    for i, a in enumerate(boxes):
        for b in boxes[i + 1 :]:
            assert not (a[0] < b[2] and b[0] < a[2] and a[1] < b[3] and b[1] < a[3]), (a, b)


@given(st.floats(0.01, 1000.0))
def test_the_scale_bar_is_a_round_length_near_a_fifth_of_the_span(span):
    bar = nice_length(span)
    mantissa = bar / 10 ** math.floor(math.log10(bar) + 1e-9)
    assert any(math.isclose(mantissa, m) for m in (1, 2, 5))
    assert span / 5 / 2.5 <= bar <= span / 5 * 2.5
