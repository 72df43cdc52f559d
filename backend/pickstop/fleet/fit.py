"""Error models learned from recorded arrivals: per station, the mean offset, covariance and
yaw error with 95% confidence intervals, and how many arrivals each rests on.

An arrival's error is its reported pose less its planned one: the position offset in the
``base`` frame of the planned pose (x along its heading; the default) or the ``map`` frame, the
yaw offset wrapped to (-pi, pi]. Arrivals are grouped by station: with a scene, the station
whose model applies at the stop (:meth:`~pickstop.scene.positioning.Positioning.station_of`;
none: the scene's global model); without, one station per tray group picked there.

Estimates (Gaussian errors, n arrivals): the sample mean with Student-t intervals; the
unbiased sample covariance, its variances with chi-square intervals and its covariance with
the normal interval of its asymptotic variance (s_xx s_yy + s_xy^2) / (n - 1); the correlation
with Fisher's z interval; the yaw mean (t) and standard deviation (chi-square); and the pick
success rate with its Wilson interval.
"""

from __future__ import annotations

import hashlib
import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any, Literal

import numpy as np

from pickstop.errors import InputError
from pickstop.fleet.arrivals import Arrival
from pickstop.frames import wrap_angle
from pickstop.scene.positioning import Positioning, rot
from pickstop.sequence.success import Rate

Frame = Literal["base", "map"]
GLOBAL = "(global)"
MIN_ARRIVALS = 20  # a fit written into a scene rests on at least this many by default
Interval = tuple[float, float]


@dataclass(frozen=True)
class StationFit:
    """What the arrivals of one station say; units metres, square metres, radians."""

    name: str  # the station's name, or GLOBAL for the scene's global model
    trays: tuple[str, ...] | None  # a tray group's trays (a station the fit names itself)
    frame: Frame
    arrivals: int
    mean: tuple[float, float]
    mean_interval: tuple[Interval, Interval]
    covariance: tuple[tuple[float, float], tuple[float, float]]
    variance_interval: tuple[Interval, Interval]  # of s_xx and s_yy
    covariance_interval: Interval  # of s_xy
    correlation: float
    correlation_interval: Interval
    #: standard deviations along the major and minor axes [m], the major axis' angle from x
    #: in (-pi/2, pi/2] [rad]
    axes: tuple[float, float, float]
    yaw_mean: float
    yaw_mean_interval: Interval
    yaw_sigma: float
    yaw_sigma_interval: Interval
    picks: Rate  # stops whose every pick finished
    positive_definite: bool  # the covariance can be written as a model


def offsets(arrivals: Sequence[Arrival], frame: Frame = "base") -> np.ndarray:
    """``(n, 3)``: each arrival's position offset [m] in ``frame`` and yaw offset [rad]."""
    out = np.zeros((len(arrivals), 3))
    for k, a in enumerate(arrivals):
        d = np.array([a.reported.x - a.planned.x, a.reported.y - a.planned.y])
        theta = a.planned.theta
        if frame == "base":
            if theta is None:
                raise InputError(
                    f"arrival {a.order_id}/{a.node_id}: no planned theta, so no base frame "
                    "(fit in the map frame)",
                    field="frame",
                )
            d = rot(theta).T @ d
        dyaw = 0.0
        if theta is not None and a.reported.theta is not None:
            dyaw = float(wrap_angle(a.reported.theta - theta))
        out[k] = (d[0], d[1], dyaw)
    return out


def _axis_angle(a: float) -> float:
    """An axis' direction [rad] in (-pi/2, pi/2] (an axis has no sign)."""
    a = float(wrap_angle(a))
    if a > math.pi / 2:
        a -= math.pi
    elif a <= -math.pi / 2:
        a += math.pi
    return a


def _t(n: int) -> float:
    from scipy import stats  # on use: it adds half a second to every command's start

    return float(stats.t.ppf(0.975, n - 1))


def _var_interval(s2: float, n: int) -> Interval:
    from scipy import stats

    lo = (n - 1) * s2 / float(stats.chi2.ppf(0.975, n - 1))
    hi = (n - 1) * s2 / float(stats.chi2.ppf(0.025, n - 1))
    return (lo, hi)


def fit_station(
    name: str, trays: tuple[str, ...] | None, arrivals: Sequence[Arrival], frame: Frame = "base"
) -> StationFit:
    """The estimates of one station from its ``arrivals`` (at least 3)."""
    n = len(arrivals)
    if n < 3:
        raise InputError(f"station {name}: {n} arrivals, a fit needs at least 3", field="log")
    e = offsets(arrivals, frame)
    xy, yaw = e[:, :2], e[:, 2]
    mu = xy.mean(0)
    C = np.cov(xy.T, ddof=1)
    t = _t(n)
    half = t * np.sqrt(np.diag(C) / n)
    sxx, syy, sxy = float(C[0, 0]), float(C[1, 1]), float(C[0, 1])
    se_xy = math.sqrt((sxx * syy + sxy * sxy) / (n - 1))
    rho = sxy / math.sqrt(sxx * syy) if sxx > 0 and syy > 0 else 0.0
    z, dz = (
        math.atanh(max(-0.999999, min(0.999999, rho))),
        1.959963984540054 / math.sqrt(max(n - 3, 1)),
    )
    w, V = np.linalg.eigh(C)
    major = V[:, 1]
    ym, ys = float(yaw.mean()), float(yaw.std(ddof=1))
    ok = sum(a.ok for a in arrivals)
    return StationFit(
        name=name,
        trays=trays,
        frame=frame,
        arrivals=n,
        mean=(float(mu[0]), float(mu[1])),
        mean_interval=((mu[0] - half[0], mu[0] + half[0]), (mu[1] - half[1], mu[1] + half[1])),
        covariance=((sxx, sxy), (sxy, syy)),
        variance_interval=(_var_interval(sxx, n), _var_interval(syy, n)),
        covariance_interval=(sxy - 1.959963984540054 * se_xy, sxy + 1.959963984540054 * se_xy),
        correlation=rho,
        correlation_interval=(math.tanh(z - dz), math.tanh(z + dz)),
        axes=(
            math.sqrt(max(w[1], 0.0)),
            math.sqrt(max(w[0], 0.0)),
            _axis_angle(math.atan2(major[1], major[0])),
        ),
        yaw_mean=ym,
        yaw_mean_interval=(ym - _t(n) * ys / math.sqrt(n), ym + _t(n) * ys / math.sqrt(n)),
        yaw_sigma=ys,
        yaw_sigma_interval=tuple(math.sqrt(v) for v in _var_interval(ys * ys, n)),  # type: ignore[arg-type]
        picks=Rate(n, ok),
        positive_definite=bool(sxx > 0 and syy > 0 and sxx * syy - sxy * sxy > 0),
    )


def group_name(trays: Sequence[str]) -> str:
    """A tray group's station name: ``trays:A:B`` (a digest of them past 64 characters)."""
    name = "trays:" + ":".join(sorted(trays))
    if len(name) <= 64:
        return name
    return "trays:" + hashlib.sha256(name.encode()).hexdigest()[:16]


def group(
    arrivals: Sequence[Arrival], positioning: Positioning | None = None
) -> dict[tuple[str, tuple[str, ...] | None], list[Arrival]]:
    """Arrivals by station: ``(name, trays)`` -> arrivals. With ``positioning`` (a scene's),
    the station whose model applies at the planned stop (GLOBAL: none); else one station per
    tray group (:func:`group_name`; an arrival without trays by its node id)."""
    out: dict[tuple[str, tuple[str, ...] | None], list[Arrival]] = {}
    for a in arrivals:
        if positioning is not None:
            name = positioning.station_of((a.planned.x, a.planned.y), a.trays)
            key: tuple[str, tuple[str, ...] | None] = (name or GLOBAL, None)
        elif a.trays:
            key = (group_name(a.trays), tuple(a.trays))
        else:
            key = (f"node:{a.node_id}", None)
        out.setdefault(key, []).append(a)
    return out


def fit(
    arrivals: Sequence[Arrival], positioning: Positioning | None = None, frame: Frame = "base"
) -> tuple[list[StationFit], list[str]]:
    """Every station's fit (those with at least 3 arrivals) and why others have none."""
    fits, notes = [], []
    for (name, trays), mine in sorted(group(arrivals, positioning).items()):
        if len(mine) < 3:
            notes.append(f"station {name}: {len(mine)} arrival(s), a fit needs at least 3")
            continue
        fits.append(fit_station(name, trays, mine, frame))
    return fits, notes


def describe(f: StationFit) -> dict[str, Any]:
    """A fit as JSON (its intervals beside each estimate)."""
    lo, hi = f.picks.interval
    return {
        "station": f.name,
        "trays": None if f.trays is None else list(f.trays),
        "frame": f.frame,
        "arrivals": f.arrivals,
        "mean": list(f.mean),
        "mean_interval": [list(i) for i in f.mean_interval],
        "covariance": [list(r) for r in f.covariance],
        "variance_interval": [list(i) for i in f.variance_interval],
        "covariance_interval": list(f.covariance_interval),
        "correlation": f.correlation,
        "correlation_interval": list(f.correlation_interval),
        "axes": {"major_sd": f.axes[0], "minor_sd": f.axes[1], "major_angle": f.axes[2]},
        "yaw_mean": f.yaw_mean,
        "yaw_mean_interval": list(f.yaw_mean_interval),
        "yaw_sigma": f.yaw_sigma,
        "yaw_sigma_interval": list(f.yaw_sigma_interval),
        "pick_success": f.picks.rate,
        "pick_success_interval": [lo, hi],
    }


def model_fields(f: StationFit) -> dict[str, Any]:
    """The error model fields a fit sets (a scene's ``error_model`` or one of its stations)."""
    return {
        "kind": "gaussian",
        "mean": [round(f.mean[0], 6), round(f.mean[1], 6)],
        "covariance": [[float(f"{c:.6g}") for c in row] for row in f.covariance],
        "yaw_mean": round(f.yaw_mean, 6),
        "yaw_sigma": round(f.yaw_sigma, 6),
        "frame": f.frame,
    }


def _writable(f: StationFit, min_arrivals: int) -> str | None:
    """Why a fit is not written as a model, or None."""
    if f.name.startswith("node:"):
        return f"station {f.name}: its picks name no tray, so no tray group to give it"
    if f.arrivals < min_arrivals:
        return f"station {f.name}: {f.arrivals} arrivals, fewer than {min_arrivals}"
    if not f.positive_definite:
        return f"station {f.name}: the covariance is not positive definite"
    return None


def into_error_model(
    em: dict[str, Any], fits: Sequence[StationFit], min_arrivals: int = MIN_ARRIVALS
) -> tuple[dict[str, Any], list[str], list[str]]:
    """``em`` (an ``error_model`` block) with the fits written into it: the global model's
    fields, a station's of the same name (its trays or zone kept), or a new tray-group
    station. Returns the block, the stations written and why the others were not."""
    out = {**em, "stations": [dict(s) for s in em.get("stations", [])]}
    written, skipped = [], []
    for f in fits:
        why = _writable(f, min_arrivals)
        if why is not None:
            skipped.append(why)
            continue
        fields = model_fields(f)
        if f.name == GLOBAL:
            out.update(fields)
        else:
            old = next((s for s in out["stations"] if s.get("name") == f.name), None)
            where = {"trays": list(f.trays)} if f.trays is not None else {}
            new = {"name": f.name, **where, **fields, "arrivals": f.arrivals}
            if old is None:
                out["stations"].append(new)
            else:
                keep = {k: old[k] for k in ("trays", "zone", "sigma") if k in old}
                old.clear()
                old.update({**new, **keep})
        written.append(f.name)
    return out, written, skipped


def document(
    fits: Sequence[StationFit],
    notes: Sequence[str],
    scene_doc: dict[str, Any] | None = None,
    min_arrivals: int = MIN_ARRIVALS,
) -> dict[str, Any]:
    """The fit as an error model file (``pickstop.error_model``): the scene's error model (or
    an empty one) with the fits written in, and a ``fit`` section with every estimate, its
    interval and arrival count."""
    base = dict((scene_doc or {}).get("error_model") or {})
    em, written, skipped = into_error_model(base, fits, min_arrivals)
    return {
        "format": "pickstop.error_model",
        "version": 1,
        "sigma": None if scene_doc is None else scene_doc.get("sigma"),
        "error_model": em,
        "fit": {
            "arrivals": sum(f.arrivals for f in fits),
            "min_arrivals": min_arrivals,
            "stations": [describe(f) for f in fits],
            "written": written,
            "not_written": [*skipped, *notes],
        },
    }
