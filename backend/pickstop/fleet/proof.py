"""A plan's tolerances proven by the exact check, per stop: the circle and the ellipse
(:func:`pickstop.fleet.tolerance.stop_shapes`) and the yaw window
(:func:`pickstop.fleet.yaw.verified_yaw_tolerance`), what ``pickstop export --verify-xy
--verify-yaw`` and the API's ``tolerances=verified`` send to a fleet.

A plan never changes, so its proof is made once and may be kept (the service keeps it per plan
id); :data:`PROVER` names the method and its constants, and a proof kept under another name is
made again.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass
from typing import Any

from pickstop.fleet import tolerance as tl
from pickstop.fleet import yaw as yw
from pickstop.fleet.pickcheck import PickChecker
from pickstop.fleet.tolerance import Ellipse, StopShapes
from pickstop.fleet.yaw import verified_yaw_tolerances
from pickstop.sequence import plan_model as pm

PROVER = (
    f"pickstop.proof 1: shapes {tl.BOUNDARY_MAX} {tl.INTERIOR_MAX} {tl.ROUNDS} {tl.ANGLES} "
    f"{tl.SIZES} {tl.SHRINK}; yaw {yw.STEP!r} {yw.LIMIT!r}"
)


@dataclass(frozen=True)
class PlanProof:
    """Per stop, in stop order: its checked circle and ellipse, and its yaw window [rad]
    (every yaw offset up to it, either way, passes at the stop's centre)."""

    shapes: tuple[StopShapes, ...]
    yaw: tuple[float, ...]

    def __post_init__(self) -> None:
        if len(self.shapes) != len(self.yaw):
            raise ValueError(f"{len(self.shapes)} shapes for {len(self.yaw)} yaw windows")

    @property
    def tests(self) -> int:
        """Exact tests (pose x tray) the shapes took."""
        return sum(s.tests for s in self.shapes)

    def to_json(self) -> dict[str, Any]:
        """As JSON (floats kept exactly: JSON numbers round-trip a double)."""
        return {"shapes": [asdict(s) for s in self.shapes], "yaw": list(self.yaw)}

    @classmethod
    def of_json(cls, doc: dict[str, Any]) -> PlanProof:
        shapes = tuple(
            StopShapes(**{**s, "ellipse": Ellipse(**s["ellipse"])}) for s in doc["shapes"]
        )
        return cls(shapes, tuple(float(t) for t in doc["yaw"]))


def prove_plan(check: PickChecker, plan: pm.Plan) -> PlanProof:
    """Every stop's circle, ellipse and yaw window, checked by ``check`` (the plan scene's
    exact test; :func:`pickstop.fleet.pickcheck.exact_checker`). Cost: per stop at most 3
    shapes x (``ROUNDS`` x 2 ``BOUNDARY_MAX`` + ``INTERIOR_MAX``) poses and 2 ``LIMIT / STEP``
    yaws, each once per tray of the stop."""
    return PlanProof(check.shapes(plan), verified_yaw_tolerances(check, plan))
