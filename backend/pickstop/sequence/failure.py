"""Expected time of failed arrivals: re-localise and re-dock, retries, then an operator.

An arrival at a stop succeeds when every tray the stop serves is graspable from where the base
landed (probability ``p``, the stop's success rate). When it fails the base re-localises and
re-docks (``relocalise_time + redock_time`` [s]) and lands anew, independently, up to
``retries`` times; when the last retry fails too an operator is called (``operator_time`` [s])
and sets the base where it picks. With ``q = 1 - p``, a stop's expected extra time is

    (relocalise_time + redock_time) * (q + q^2 + ... + q^retries) + operator_time * q^(retries + 1)

and a plan's expected time is its predicted time plus the sum of its stops' extra times.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class FailureCosts:
    """What a failed arrival costs: ``retry_time`` [s] per re-localise and re-dock,
    ``retries`` of them at most, then ``operator_time`` [s] for an operator's call."""

    retry_time: float
    retries: int
    operator_time: float

    @classmethod
    def of(cls, model: object) -> FailureCosts:
        """From a scene's :class:`~pickstop.scene.model.FailureModel` (or anything with its
        fields)."""
        return cls(
            float(model.relocalise_time) + float(model.redock_time),  # type: ignore[attr-defined]
            int(model.retries),  # type: ignore[attr-defined]
            float(model.operator_time),  # type: ignore[attr-defined]
        )


@dataclass(frozen=True)
class StopFailures:
    """A stop's expected failures per run: re-docks, operator calls, extra time [s]."""

    retries: float
    operator: float
    time: float


def expected_retries(p: np.ndarray | float, retries: int) -> np.ndarray:
    """Expected re-docks per arrival at success rate ``p`` (array or scalar)."""
    q = 1.0 - np.clip(np.asarray(p, float), 0.0, 1.0)
    out = np.zeros_like(q)
    term = np.ones_like(q)
    for _ in range(retries):
        term = term * q
        out = out + term
    return out


def operator_probability(p: np.ndarray | float, retries: int) -> np.ndarray:
    """Probability that every attempt fails and an operator is called."""
    q = 1.0 - np.clip(np.asarray(p, float), 0.0, 1.0)
    return q ** (retries + 1)


def failure_time(p: np.ndarray | float, costs: FailureCosts) -> np.ndarray:
    """Expected extra time [s] of a stop with success rate ``p`` (array or scalar)."""
    return costs.retry_time * expected_retries(p, costs.retries) + (
        costs.operator_time * operator_probability(p, costs.retries)
    )


def stop_failures(p: float, costs: FailureCosts) -> StopFailures:
    """:func:`expected_retries`, :func:`operator_probability` and :func:`failure_time` of one
    stop."""
    return StopFailures(
        float(expected_retries(p, costs.retries)),
        float(operator_probability(p, costs.retries)),
        float(failure_time(p, costs)),
    )
