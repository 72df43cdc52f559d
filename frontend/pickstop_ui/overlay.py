"""The page side of the planner: hover and click info, the panel's place, and a pan guard.

Viser sends the page no hover events and has no tooltips of its own, so one script (sent once;
the server replays it to every browser that connects later) does three things in the page:

- **Info on hover and click.** It casts the pointer's ray into the world (viser's camera and
  root frame, read from the viewer's test points) and tests it against the shapes of
  :func:`pickstop_ui.hover.hover_data`, which the planner writes as JSON into a hidden element
  of the panel (an ordinary panel update, so only the newest is kept or replayed); a tooltip
  follows the pointer, and a click pins it until the next press.
- **Where the panel is.** It reports the view's size and the panel's left edge [CSS px]
  through a hidden text field, so camera presets frame the scene beside the panel.
- **Panning moves nothing.** While a right or middle button is down, the viewer's
  object pointer events are off: a pan or orbit that starts over the gizmo moves the camera,
  never the selected item (the gizmo answers the left button only).
"""

from __future__ import annotations

import json
from typing import Any

import viser
from viser import _messages

HOVER_ID = "pickstop-hover"

_SCRIPT = """(() => {
  if (window.__pickstopOverlay) return;
  const LAYOUT = %(layout)s;
  const st = { text: null, data: null, pinned: false, down: null, guard: null, sent: "" };
  window.__pickstopOverlay = st;
  const data = () => {
    const el = document.getElementById("%(hover_id)s");
    if (!el) return null;
    if (el.textContent !== st.text) {
      st.text = el.textContent;
      try { st.data = JSON.parse(st.text); } catch (e) { st.data = null; }
    }
    return st.data;
  };
  const tip = document.createElement("div");
  tip.id = "pickstop-tip";
  tip.style.cssText = "position:fixed;z-index:1000;pointer-events:none;display:none;" +
    "background:rgba(255,255,255,0.96);border:1px solid #888;border-radius:4px;" +
    "padding:4px 7px;font:12px/1.35 sans-serif;color:#222;white-space:pre-line;max-width:380px";
  document.body.appendChild(tip);
  const ray = (cx, cy) => {
    const m = window.__viserMutable;
    if (!m || !m.camera || !m.canvas) return null;
    const cam = m.camera, r = m.canvas.getBoundingClientRect();
    if (cx < r.left || cx > r.right || cy < r.top || cy > r.bottom) return null;
    cam.updateMatrixWorld();
    const o = cam.position.clone().setFromMatrixPosition(cam.matrixWorld);
    const p = cam.position.clone()
      .set(((cx - r.left) / r.width) * 2 - 1, -((cy - r.top) / r.height) * 2 + 1, 0.5)
      .unproject(cam);
    const root = m.nodeRefFromName[""];
    if (root) {
      root.updateMatrixWorld();
      const inv = root.matrixWorld.clone().invert();
      o.applyMatrix4(inv); p.applyMatrix4(inv);
    }
    const d = p.clone().sub(o).normalize();
    return { o, d };
  };
  const at = (q, z) => {
    if (Math.abs(q.d.z) < 1e-9) return null;
    const t = (z - q.o.z) / q.d.z;
    return t < 0 ? null : [q.o.x + t * q.d.x, q.o.y + t * q.d.y, t];
  };
  const inRing = (p, ring) => {
    let inside = false;
    for (let i = 0, j = ring.length - 1; i < ring.length; j = i++) {
      const [xi, yi] = ring[i], [xj, yj] = ring[j];
      if ((yi > p[1]) !== (yj > p[1]) && p[0] < ((xj - xi) * (p[1] - yi)) / (yj - yi) + xi)
        inside = !inside;
    }
    return inside;
  };
  const textAt = (cx, cy) => {
    const d = data(), q = ray(cx, cy);
    if (!d || !q) return null;
    let best = null;
    for (const it of d.items) {
      const p = at(q, it.top);
      if (!p) continue;
      const c = Math.cos(-it.yaw), s = Math.sin(-it.yaw);
      const dx = p[0] - it.cx, dy = p[1] - it.cy;
      if (Math.abs(c * dx - s * dy) <= it.hx && Math.abs(s * dx + c * dy) <= it.hy &&
          (best === null || p[2] < best[0])) best = [p[2], it.text];
    }
    if (best) return best[1];
    const f = at(q, 0.0);
    if (!f) return null;
    const near = (list) => {
      let b = null;
      for (const c of list) {
        const dist = Math.hypot(f[0] - c.x, f[1] - c.y);
        if (dist <= c.r && (b === null || dist < b[0])) b = [dist, c.text];
      }
      return b && b[1];
    };
    const hit = near(d.stops) || near(d.circles);
    if (hit) return hit;
    let reg = null;
    for (const g of d.regions) {
      let inside = false;
      for (const ring of g.rings) if (inRing(f, ring)) inside = !inside;
      if (inside && (reg === null || g.area < reg[0])) reg = [g.area, g.text];
    }
    return reg && reg[1];
  };
  const show = (text, cx, cy) => {
    if (!text) { tip.style.display = "none"; return; }
    tip.textContent = text;
    tip.style.display = "block";
    const w = tip.offsetWidth, h = tip.offsetHeight;
    tip.style.left = Math.min(cx + 14, window.innerWidth - w - 4) + "px";
    tip.style.top = Math.min(cy + 14, window.innerHeight - h - 4) + "px";
  };
  let pending = null;
  window.addEventListener("pointermove", (e) => {
    if (e.buttons) { if (!st.pinned) tip.style.display = "none"; return; }
    if (st.pinned) return;
    const cx = e.clientX, cy = e.clientY;
    if (pending === null) pending = requestAnimationFrame(() => {
      pending = null;
      show(textAt(cx, cy), cx, cy);
    });
  }, { passive: true });
  const r3f = () => {
    const sc = window.__viserMutable && window.__viserMutable.scene;
    const root = sc && sc.__r3f && sc.__r3f.root;
    return root && root.getState ? root.getState() : null;
  };
  window.addEventListener("pointerdown", (e) => {
    st.down = [e.clientX, e.clientY, e.button];
    st.pinned = false;
    tip.style.display = "none";
    if (e.button !== 0) {
      const s = r3f();
      if (s && s.events) { s.events.enabled = false; st.guard = e.pointerId; }
    }
  }, { capture: true });
  const release = (e) => {
    if (st.guard !== null) {
      const s = r3f();
      if (s && s.events) s.events.enabled = true;
      st.guard = null;
    }
    const d = st.down;
    st.down = null;
    if (e.type === "pointerup" && d && d[2] === 0 &&
        Math.hypot(e.clientX - d[0], e.clientY - d[1]) < 4) {
      const text = textAt(e.clientX, e.clientY);
      if (text) { show(text, e.clientX, e.clientY); st.pinned = true; }
    }
  };
  window.addEventListener("pointerup", release, { capture: true });
  window.addEventListener("pointercancel", release, { capture: true });
  const report = () => {
    const m = window.__viserMutable;
    if (!m || !m.canvas || !m.sendMessage) return;
    const r = m.canvas.getBoundingClientRect();
    const panel = document.querySelector('[data-testid="floating-panel"]');
    const left = panel ? panel.getBoundingClientRect().left - r.left : r.width;
    const value = [r.width, r.height, left].map((v) => Math.round(v)).join(",");
    if (value !== st.sent) {
      st.sent = value;
      m.sendMessage({ type: "GuiUpdateMessage", uuid: LAYOUT, updates: { value } });
    }
  };
  setInterval(report, 500);
})();"""


def hover_element(data: dict[str, Any]) -> str:
    """The hidden element holding ``data`` as JSON (safe inside HTML)."""
    text = json.dumps(data, separators=(",", ":")).replace("</", "<\\/")
    return f'<script type="application/json" id="{HOVER_ID}">{text}</script>'


def parse_layout(value: str) -> tuple[float, float, float] | None:
    """The page's report ``"width,height,panel_left"`` [CSS px], None if malformed."""
    try:
        w, h, left = (float(v) for v in value.split(","))
    except ValueError:
        return None
    if not (w > 0 and h > 0):
        return None
    return w, h, min(max(left, 0.0), w)


class Overlay:
    """The page script and its two panel elements for one planner window."""

    def __init__(self, server: viser.ViserServer) -> None:
        gui = server.gui
        self.layout = gui.add_text("layout", "", visible=False)
        self._hover = gui.add_html(hover_element({"items": [], "stops": [], "circles": [],
                                                  "regions": []}))  # fmt: skip
        self._last = ""
        source = _SCRIPT % {"layout": json.dumps(self.layout._impl.uuid), "hover_id": HOVER_ID}
        server.gui._websock_interface.queue_message(_messages.RunJavascriptMessage(source))

    def show(self, data: dict[str, Any]) -> None:
        """Make ``data`` what the page tells on hover (sent only when it changed)."""
        html = hover_element(data)
        if html != self._last:
            self._last = html
            self._hover.content = html
