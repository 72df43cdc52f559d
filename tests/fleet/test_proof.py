"""A plan's proof as JSON: kept and read back, every float exactly."""

from __future__ import annotations

import json
import math

import pytest

from pickstop.fleet.proof import PROVER, PlanProof
from pickstop.fleet.tolerance import Ellipse, StopShapes


def test_a_proof_reads_back_exactly_from_its_json():
    shapes = (
        StopShapes(0.1 / 3, Ellipse.of(0.31, 0.2, 2.0), 0.00625, 0.0125, 4321, 0.7),
        StopShapes(0.0, Ellipse(0.0, 0.0, 0.0), 0.00625, 0.0125, 1, 0.01),
    )
    proof = PlanProof(shapes, (math.radians(10.0), 0.0))
    back = PlanProof.of_json(json.loads(json.dumps(proof.to_json())))
    assert back == proof and back.tests == 4322
    assert "yaw" in PROVER and "shapes" in PROVER
    with pytest.raises(ValueError):
        PlanProof(shapes, (0.0,))
