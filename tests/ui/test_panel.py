"""The panel's words as pure functions of a plan or a problem (no browser)."""

from __future__ import annotations

from pickstop_ui import panel
from pickstop_ui.client import ApiProblem, StoredScene


def test_a_verified_plan_reads_quick_then_final(plans):
    exact, _ = plans
    quick = panel.plan_status(exact, False, 7, 123.4, 120.0, None)
    assert quick.startswith("**Status:** plan drawn · plan #7 in 123 ms")
    assert "last exact plan 120 ms" in quick and "⏳ success rates (Monte Carlo)…" in quick
    final = panel.plan_status(exact, True, 7, 1500.0, 120.0, 1380.0)
    said = f"ready — {len(exact.stops)} stops cover {len(exact.trays)} trays · plan #7"
    assert said in final and final.endswith("last Monte Carlo 1380 ms")
    assert "⏳" not in final
    text = panel.summary(exact, final=False)
    assert f"- Stops: **{exact.totals.stops}** (naive {len(exact.naive.stops)})" in text
    assert f"**σ = {exact.parameters.sigma:.3f} m**" in text and "computing…" in text
    assert "PREVIEW" not in text
    stops = panel.stops_list(exact)
    assert stops.startswith("**Stops**") and stops.count("→") == len(exact.stops)
    assert f"r = {exact.stops[0].inscribed_radius:.3f} m" in stops
    named = panel.stops_list(exact, {exact.stops[0].trays[0]: "bolts M6"})
    assert "bolts M6" in named.splitlines()[2] and exact.stops[0].trays[0] not in named


def test_a_preview_says_so_everywhere(plans):
    _, preview = plans
    status = panel.plan_status(preview, False, 9, 40.0, None, None)
    assert "preview (not verified) · plan #9 in 40 ms" in status and "⏳" not in status
    text = panel.summary(preview, final=False)
    assert text.startswith(panel.PREVIEW_HEAD) and "Success: — (preview)" in text


def test_rejected_reasons_are_listed_once_and_bounded(plans):
    exact, _ = plans
    reasons = {c.reason for c in exact.candidates if c.status == "rejected" and c.reason}
    stops = panel.stops_list(exact)
    if reasons:
        assert "**Rejected candidates:**" in stops
        listed = [line for line in stops.splitlines() if line.startswith("- ")]
        assert len(listed) == min(len(reasons), panel.MAX_REASONS)
        assert len(set(listed)) == len(listed)
    else:
        assert "Rejected" not in stops


def test_problems_name_the_field_and_keep_the_last_plan_in_view():
    e = ApiProblem(422, "Infeasible plan", "no plan with sigma = 0.500 m", "sigma")
    assert panel.failure_status(e) == "**Status:** no plan — ⚠ Infeasible plan (field `sigma`)"
    assert panel.failure_status(ApiProblem(0, "API unreachable", "x")).endswith("unreachable")
    assert "greyed out" in panel.failure_summary(e) and e.detail in panel.failure_summary(e)
    running = panel.status_line("plan drawn", 3, 50, 50, "success rates (Monte Carlo)")
    failed = panel.success_rates_failed(running, ApiProblem(500, "Server error", "boom"))
    assert (
        failed == "**Status:** plan drawn · plan #3 in 50 ms · last exact plan 50 ms"
        " · ⚠ success rates failed: Server error"
    )


def test_saving_words():
    stored = StoredScene("s1", "e", 4, {})
    assert panel.scene_revision(stored) == "Scene `s1`, revision 4"
    assert panel.scene_revision(stored, saved=True) == "Saved: scene `s1`, revision 4"
    assert "Save conflict" in panel.save_problem(ApiProblem(412, "Precondition failed", "x"))
    assert panel.save_problem(ApiProblem(422, "Invalid scene", "trays: empty")) == (
        "⚠ **Not saved:** Invalid scene: trays: empty"
    )
    assert (
        panel.waiting_line("sigma [m] changed") == "**Status:** ⏳ exact plan… (sigma [m] changed)"
    )


def test_a_colliding_travel_posture_is_said_in_the_panel():
    from pickstop_ui.robot_model import RobotDrawing

    pairs = [("arm_4_link", "torso_lift_link")] + [(f"a{k}", "b") for k in range(5)]
    robot = RobotDrawing("bot", None, ["j"], {}, {"j": 0.0}, pairs)
    line = panel.travel_line(robot)
    assert "bot's travel posture is not collision-free" in line
    assert "arm_4_link – torso_lift_link" in line and "and 2 more" in line and "`travel`" in line
    free = RobotDrawing("bot", None, ["j"], {}, {"j": 0.0}, [])
    assert panel.travel_line(free) == "" and panel.travel_line(None) == ""
    assert free.travel_theta(["j"]) == [0.0]
