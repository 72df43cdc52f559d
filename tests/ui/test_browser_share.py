"""Nothing leaves the plant: the page has no share control, and a share request sent to the
planner by hand opens no tunnel."""

from __future__ import annotations

import time

from tests.ui import browser as b

pytestmark = b.needs_chromium


def test_the_share_control_is_absent_and_a_share_request_opens_no_tunnel(pg, app):
    names = pg.evaluate(
        """() => [...document.querySelectorAll('button, a, [role=button]')].map(
               e => [e.innerText, e.getAttribute('aria-label'), e.getAttribute('title')]
                    .filter(Boolean).join(' '))"""
    )
    assert not [n for n in names if "share" in n.lower()], names
    assert "share" not in pg.inner_text("body").lower()
    pg.evaluate("() => window.__viserMutable.sendMessage({type: 'ShareUrlRequest'})")
    time.sleep(2.0)
    assert app.server._share_tunnel is None
    assert app.server.request_share_url() is None and app.server._share_tunnel is None
