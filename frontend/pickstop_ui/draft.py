"""Draft resolution: the 3D view drawn at a lower pixel ratio while the engineer edits.

A browser without a GPU renders WebGL in software (SwiftShader, llvmpipe), where a frame's
cost grows with its pixels: at 1280x800 a frame of the planner takes 80-200 ms, too slow for
ten previews a second or a slider step redrawn within 150 ms. From a change (a drag, a
slider step) until the engineer pauses (the success rates of the plan are drawn), such a
browser draws at ``scale`` times its device pixel ratio (0.35: an eighth of the pixels), then
at full resolution again. Only the resolution changes: what is drawn, and how a preview is
told from a verified plan, stay the same. A browser with a GPU keeps its full resolution.

The switch lives in the page: one script, sent once (the server replays it to every browser
that connects later), watches a hidden element of the panel and sets the viewer's pixel
ratio through viser's dev-settings store (the one its ``?fixedDpr=`` URL parameter sets),
restoring the value it found. The element's content is an ordinary panel update, so only the
newest state is ever kept or replayed.
"""

from __future__ import annotations

import viser
from viser import _messages

ATTR = "data-pickstop-draft"
#: The draft's pixel ratio as a fraction of the device's: about an eighth of the pixels, so
#: that headless Chromium here draws ten previews a second or more while a tray is dragged.
DRAFT_SCALE = 0.35

_SCRIPT = """(() => {
  if (window.__pickstopDraft) return;
  const SCALE = %(scale)r;
  const state = { saved: undefined, software: null };
  window.__pickstopDraft = state;
  const isSoftware = () => {
    const canvas = window.__viserMutable && window.__viserMutable.canvas;
    const gl = canvas && (canvas.getContext("webgl2") || canvas.getContext("webgl"));
    if (!gl) return null;
    const ext = gl.getExtension("WEBGL_debug_renderer_info");
    const name = String(gl.getParameter(ext ? ext.UNMASKED_RENDERER_WEBGL : gl.RENDERER));
    return /swiftshader|llvmpipe|softpipe|software/i.test(name);
  };
  const apply = () => {
    const el = document.querySelector("[%(attr)s]");
    const on = el !== null && el.getAttribute("%(attr)s") === "on";
    const points = window.__viserTestpoints;
    if (!points || !points.devSettings) return;
    const store = points.devSettings;
    if (on && state.saved === undefined) {
      if (state.software === null) state.software = isSoftware();
      if (!state.software) return;
      state.saved = store.get().fixedDpr;
      store.set({ fixedDpr: SCALE * window.devicePixelRatio });
    } else if (!on && state.saved !== undefined) {
      store.set({ fixedDpr: state.saved });
      state.saved = undefined;
    }
  };
  new MutationObserver(apply).observe(document.body, {
    subtree: true, childList: true, attributes: true, attributeFilter: ["%(attr)s"],
  });
})();"""


def _marker(on: bool) -> str:
    return f'<div {ATTR}="{"on" if on else "off"}" style="display:none"></div>'


class DraftResolution:
    """The draft switch of one planner window (every browser connected to it)."""

    def __init__(self, server: viser.ViserServer, scale: float = DRAFT_SCALE) -> None:
        """scale: the draft's pixel ratio as a fraction of the device's, in (0, 1]."""
        if not 0.0 < scale <= 1.0:
            raise ValueError(f"draft scale must be in (0, 1], got {scale}")
        self.on = False
        self._element = server.gui.add_html(_marker(False))
        source = _SCRIPT % {"scale": float(scale), "attr": ATTR}
        server.gui._websock_interface.queue_message(_messages.RunJavascriptMessage(source))

    def set(self, on: bool) -> None:
        """Draft resolution while ``on`` (the engineer is editing), full resolution after."""
        if on != self.on:
            self.on = on
            self._element.content = _marker(on)
