"""The planner panel's text: pure functions from a plan (or a problem) to Markdown."""

from __future__ import annotations

import math

from pickstop.sequence.plan_model import Plan
from pickstop_ui.client import ApiProblem, StoredScene
from pickstop_ui.robot_model import RobotDrawing

MAX_REASONS = 4  # distinct rejection reasons listed under the stops

PREVIEW_HEAD = (
    "**PREVIEW — not verified:** regions carried with the moved tray; the exact plan follows "
    "on release."
)


def status_line(phase: str, seq: int, ms: float, exact_ms: float | None, busy: str | None) -> str:
    """The panel's status: what is shown, how long it took, and what is running."""
    running = f" · ⏳ {busy}…" if busy else ""
    last = f" · last exact plan {exact_ms:.0f} ms" if exact_ms is not None else ""
    return f"**Status:** {phase} · plan #{seq} in {ms:.0f} ms{last}{running}"


def waiting_line(cause: str) -> str:
    """The status while the exact plan of a change is computed."""
    return f"**Status:** ⏳ exact plan… ({cause})"


def plan_status(
    plan: Plan, final: bool, seq: int, ms: float, exact_ms: float | None, mc_ms: float | None
) -> str:
    """The status of a drawn plan: a preview, the quick exact plan (success rates running)
    or the final one with the Monte Carlo's time."""
    if not plan.verified:
        return status_line("preview (not verified)", seq, ms, exact_ms, None)
    if not final:
        return status_line("plan drawn", seq, ms, exact_ms, "success rates (Monte Carlo)")
    mc = f" · last Monte Carlo {mc_ms:.0f} ms" if mc_ms else ""
    said = f"ready — {len(plan.stops)} stops cover {len(plan.trays)} trays"
    return status_line(said, seq, ms, exact_ms, None) + mc


def success_text(plan: Plan, final: bool) -> str:
    t = plan.totals
    if not plan.verified:
        return "— (preview)"
    if not final:
        return "computing…"
    if t.success is None or t.success_interval is None:
        return "—"
    lo, hi = t.success_interval
    return f"{t.success:.1%} (95% interval {lo:.1%} to {hi:.1%})"


def summary(plan: Plan, final: bool) -> str:
    """Sigma and rule, stops, route, time against the naive plan, success, candidates."""
    t, n = plan.totals, plan.naive
    rejected = sum(c.status == "rejected" for c in plan.candidates)
    head = [PREVIEW_HEAD, ""] if not plan.verified else []
    return "\n".join(
        [
            *head,
            f"**σ = {plan.parameters.sigma:.3f} m**, rule *{plan.parameters.rule}*",
            f"- Stops: **{t.stops}** (naive {len(n.stops)})",
            f"- Route: **{t.route_length:.2f} m**",
            f"- Time: **{t.time.total:.1f} s** (naive {n.time.total:.1f} s, saving "
            f"**{n.saving_fraction:.1%}**)",
            f"- Success: {success_text(plan, final)}",
            f"- Candidates: {len(plan.candidates)}, rejected {rejected}",
        ]
    )


def stops_list(plan: Plan, names: dict[str, str] | None = None) -> str:
    """Each stop with its trays (by ``names``, else id), circle radius and success rate; then
    why candidates lost."""
    names = names or {}
    lines = []
    for s in plan.stops:
        ok = "" if s.success is None else f" · {s.success.rate:.1%}"
        lines.append(
            f"{s.index + 1}. ({s.x:.2f}, {s.y:.2f}) m, yaw {math.degrees(s.yaw):.0f}° → "
            f"{', '.join(names.get(t, t) for t in s.trays)} · r = {s.inscribed_radius:.3f} m{ok}"
        )
    why = sorted({c.reason for c in plan.candidates if c.status == "rejected" and c.reason})
    if why:
        lines.append("\n**Rejected candidates:**")
        lines += [f"- {w}" for w in why[:MAX_REASONS]]
    return "**Stops**\n\n" + "\n".join(lines)


def failure_status(e: ApiProblem) -> str:
    what = f" (field `{e.field}`)" if e.field else ""
    return f"**Status:** no plan — ⚠ {e.title}{what}"


def failure_summary(e: ApiProblem) -> str:
    return f"**{e.title}.** {e.detail}\n\n*The last valid plan is shown greyed out.*"


def success_rates_failed(status: str, e: ApiProblem) -> str:
    """The status once the Monte Carlo failed: the quick plan stays, without success rates."""
    return status.split(" · ⏳")[0] + f" · ⚠ success rates failed: {e.title}"


MEASURE_HELP = (
    "Click two points in the 3D view (on an item or the floor); a third click starts anew. "
    "Esc or *Stop measuring* ends the tool."
)


def selected_line(key: tuple[str, str] | None, name: str | None) -> str:
    """What is selected, and how to act on it."""
    if key is None:
        return "*Nothing selected.* Click a tray or an obstacle to move or turn it."
    kind = "tray" if key[0] == "trays" else "obstacle"
    if name and name != key[1]:
        named = f"**{name}** ({kind} `{key[1]}`)"
    else:
        named = f"**{key[1]}** ({kind})"
    return f"Selected: {named}. Drag the gizmo's arrows to move it, its ring to turn it."


def scene_revision(stored: StoredScene, saved: bool = False, dirty: bool = False) -> str:
    """The stored scene's line: its id and revision, and whether the layout on screen differs."""
    head = f"{'Saved: s' if saved else 'S'}cene `{stored.id}`, revision {stored.revision}"
    return head + (" · **unsaved changes**" if dirty else "")


def save_problem(e: ApiProblem) -> str:
    if e.status == 412:
        return (
            "⚠ **Save conflict:** the scene was changed by someone else since you opened it. "
            "Nothing was overwritten; reload to see their version."
        )
    return f"⚠ **Not saved:** {e.title}: {e.detail}"


def travel_line(robot: RobotDrawing | None) -> str:
    """A warning when the robot's travel posture is not collision-free (empty otherwise)."""
    if robot is None or not robot.travel_collisions:
        return ""
    pairs = ", ".join(f"{a} – {b}" for a, b in robot.travel_collisions[:4])
    more = len(robot.travel_collisions) - 4
    pairs += f" and {more} more" if more > 0 else ""
    return (
        f"⚠ **{robot.name}'s travel posture is not collision-free** ({pairs}): set `travel` "
        "in its robot config (`pickstop robot check` shows it)."
    )
