"""Fits of arrival logs drawn from known models: estimates within their intervals, intervals
that cover the truth as often as they say, stations grouped as the scene says, and fits written
into error models and scenes only where they rest on enough arrivals."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from pickstop.fleet import fit as ft
from pickstop.fleet.arrivals import Arrival, PickOutcome, Pose
from pickstop.frames import wrap_angle
from pickstop.scene.error_file import parse_error_file
from pickstop.scene.load import parse_scene
from pickstop.scene.positioning import ErrorDist, Positioning, Station, of_scene

EXAMPLES = Path(__file__).parents[2] / "examples" / "scenes"
TRUTH = ErrorDist(
    "gaussian",
    mean=(0.03, -0.012),
    covariance=((9e-4, 2.4e-4), (2.4e-4, 1.6e-4)),  # sd 30 mm along, 12.6 mm across, rho 0.27
    yaw_mean=math.radians(0.8),
    yaw_sigma=math.radians(1.5),
)


def arrivals_of(
    dist: ErrorDist, n: int, seed: int, stops=((1.0, 2.0, 0.7, ("t1",)),), ok=0.9
) -> list[Arrival]:
    """``n`` arrivals at each stop ``(x, y, yaw, trays)``, landing off by ``dist``; a share
    ``ok`` of them with their pick finished."""
    rng = np.random.default_rng(seed)
    out = []
    for x, y, yaw, trays in stops:
        dxy, dyaw = dist.sample(n, rng, yaw)
        for k in range(n):
            done = bool(rng.random() < ok)
            out.append(
                Arrival(
                    order_id=f"o{k}", node_id="stop0", sequence_id=2, stop=0, trays=list(trays),
                    manufacturer="m", serial_number="s", planned=Pose(x=x, y=y, theta=yaw),
                    reported=Pose(x=x + dxy[k, 0], y=y + dxy[k, 1],
                                  theta=float(wrap_angle(yaw + dyaw[k]))),
                    time="2026-01-01T00:00:00.000Z",
                    picks=[PickOutcome(action_id="a", tray_id=trays[0], part_id="p",
                                       status="FINISHED" if done else "FAILED")],
                    ok=done,
                )
            )  # fmt: skip
    return out


def within(value, interval) -> bool:
    return interval[0] <= value <= interval[1]


def test_a_fit_of_500_arrivals_recovers_the_model_within_its_intervals():
    (f,), notes = ft.fit(arrivals_of(TRUTH, 500, seed=11))
    assert notes == [] and f.arrivals == 500 and f.name == "trays:t1" and f.trays == ("t1",)
    C = TRUTH.cov()
    assert within(TRUTH.mean[0], f.mean_interval[0])
    assert within(TRUTH.mean[1], f.mean_interval[1])
    assert within(C[0, 0], f.variance_interval[0]) and within(C[1, 1], f.variance_interval[1])
    assert within(C[0, 1], f.covariance_interval)
    assert within(C[0, 1] / math.sqrt(C[0, 0] * C[1, 1]), f.correlation_interval)
    assert within(TRUTH.yaw_mean, f.yaw_mean_interval)
    assert within(TRUTH.yaw_sigma, f.yaw_sigma_interval)
    assert f.axes[0] > f.axes[1] and abs(f.axes[2]) < math.radians(25)  # long along x
    assert within(0.9, f.picks.interval) and f.positive_definite


def test_the_intervals_cover_the_truth_as_often_as_they_say():
    """200 logs of 50 arrivals each: every 95% interval holds the truth in 90-99% of them."""
    C = TRUTH.cov()
    truth = {
        "mx": TRUTH.mean[0], "sxx": C[0, 0], "sxy": C[0, 1], "yaw": TRUTH.yaw_mean,
        "yaw_sd": TRUTH.yaw_sigma,
    }  # fmt: skip
    hits = dict.fromkeys(truth, 0)
    for seed in range(200):
        (f,), _ = ft.fit(arrivals_of(TRUTH, 50, seed=seed))
        got = {
            "mx": f.mean_interval[0], "sxx": f.variance_interval[0],
            "sxy": f.covariance_interval, "yaw": f.yaw_mean_interval,
            "yaw_sd": f.yaw_sigma_interval,
        }  # fmt: skip
        for k in truth:
            hits[k] += within(truth[k], got[k])
    assert all(180 <= h <= 199 for h in hits.values()), hits


def test_a_map_frame_fit_sees_the_model_turned_by_the_stops_yaw():
    yaw = 0.7
    (f,), _ = ft.fit(arrivals_of(TRUTH, 3000, seed=2), frame="map")
    mu, C = TRUTH.in_map(yaw)
    assert f.mean == pytest.approx(tuple(mu), abs=2e-3)
    assert np.array(f.covariance) == pytest.approx(C, abs=6e-5)


def test_arrivals_group_by_the_scenes_stations_or_by_tray_group():
    stops = ((0.0, 0.0, 0.0, ("a",)), (5.0, 0.0, 0.0, ("b",)), (9.0, 9.0, 0.0, ("c",)))
    logs = arrivals_of(TRUTH, 10, seed=3, stops=stops)
    pos = Positioning(TRUTH, (Station("zone", TRUTH, zone=((4, -1), (6, -1), (6, 1), (4, 1))),
                              Station("shelf", TRUTH, trays=frozenset({"a"}))))  # fmt: skip
    assert sorted(k for k, _ in ft.group(logs, pos)) == [ft.GLOBAL, "shelf", "zone"]
    assert sorted(k for k, _ in ft.group(logs)) == ["trays:a", "trays:b", "trays:c"]
    fits, notes = ft.fit(logs[:12])
    assert [f.name for f in fits] == ["trays:a"] and notes == [
        "station trays:b: 2 arrival(s), a fit needs at least 3"
    ]


def test_fits_are_written_where_they_rest_on_enough_arrivals():
    doc = json.loads((EXAMPLES / "five_trays.json").read_text())
    trays = [t["id"] for t in doc["trays"]]
    left = {"name": "left", "trays": trays[:2], "sigma": 0.02}
    doc["error_model"] = {"kind": "gaussian", "yaw_sigma": 0.01, "stations": [left]}
    scene = parse_scene(doc)

    stops = ((0.5, 0.5, 1.0, (trays[0],)), (3.0, 3.0, 0.0, (trays[3],)))
    logs = arrivals_of(TRUTH, 40, seed=4, stops=stops)[:70]  # 40 at "left", 30 elsewhere
    fits, notes = ft.fit(logs, of_scene(scene))
    out = ft.document(fits, notes, doc, min_arrivals=35)
    assert out["fit"]["written"] == ["left"]
    assert out["fit"]["not_written"] == ["station (global): 30 arrivals, fewer than 35"]
    em = out["error_model"]
    (left,) = em["stations"]
    assert left["trays"] == trays[:2] and left["sigma"] == 0.02  # kept
    assert left["arrivals"] == 40 and left["kind"] == "gaussian" and left["frame"] == "base"
    assert em["yaw_sigma"] == 0.01 and "mean" not in em  # the global model untouched
    fitted = parse_scene({**doc, "error_model": em})
    st = of_scene(fitted).at((0.5, 0.5), [trays[0]])
    assert st.mean == pytest.approx(TRUTH.mean, abs=0.01) and st.covariance is not None
    f = parse_error_file(json.loads(json.dumps(out)))
    assert f.fit["stations"][0]["station"] == ft.GLOBAL
    # with no scene: tray-group stations, written as such
    fits, notes = ft.fit(logs)
    plain = ft.document(fits, notes, None, min_arrivals=20)
    assert {s["name"]: s["trays"] for s in plain["error_model"]["stations"]} == {
        f"trays:{trays[0]}": [trays[0]],
        f"trays:{trays[3]}": [trays[3]],
    }
    assert parse_error_file(plain).positioning().at((0, 0), [trays[3]]).name == f"trays:{trays[3]}"
