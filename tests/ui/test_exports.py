"""The PNG to hand on: the render under a title, the plan's figures and the legend beside it."""

from __future__ import annotations

import io

import numpy as np
from PIL import Image

from pickstop_ui.exports import LEGEND_W, TITLE_H, compose_png, figure_lines


def test_the_page_frames_the_render_with_a_title_figures_and_a_legend(plans):
    exact, _ = plans
    render = np.zeros((120, 200, 4), np.uint8)
    render[..., 1] = 200  # opaque green
    render[..., 3] = 255
    render[:10, :10, 3] = 0  # a transparent corner shows white
    lines = figure_lines(exact)
    img = np.asarray(Image.open(io.BytesIO(compose_png(render, "Cell 7", lines))).convert("RGB"))
    assert img.shape == (120 + TITLE_H, 200 + LEGEND_W, 3)
    assert (img[TITLE_H + 20 :, 20:180] == (0, 200, 0)).all()
    assert (img[TITLE_H + 2, 2] == 255).all()
    assert (img[: TITLE_H - 2, :200].min(axis=-1) < 100).sum() > 50  # the title's letters
    assert (img[TITLE_H:, 200:].min(axis=-1) < 100).sum() > 300  # figures and legend
    assert lines[0] == f"{exact.totals.stops} stops for {len(exact.trays)} trays"
    assert f"route {exact.totals.route_length:.2f} m" in lines


def test_a_preview_says_so_and_no_plan_says_so(plans):
    _, preview = plans
    assert "preview: not verified" in figure_lines(preview)
    assert figure_lines(None) == ["No plan."]
