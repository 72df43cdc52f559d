"""Positioning error models: the isotropic case draws what it always drew; anisotropic,
biased, turned models against their moments, density and disc probability; which station's
model applies where; scenes and model files with mistakes are refused naming the field."""

from __future__ import annotations

import copy
import json
import math
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from pickstop.errors import InputError
from pickstop.scene.error_file import parse_error_file
from pickstop.scene.load import parse_scene
from pickstop.scene.model import SceneError
from pickstop.scene.positioning import YAW_LATTICE, ErrorDist, Positioning, Station, of_scene, rot

EXAMPLES = Path(__file__).parents[2] / "examples" / "scenes"
ANISO = ErrorDist(
    "gaussian",
    mean=(0.03, -0.01),
    covariance=((0.0016, 0.0003), (0.0003, 0.0004)),
    yaw_mean=math.radians(1.0),
    yaw_sigma=math.radians(2.0),
)


def _old_sample(kind, sigma, yaw_sigma, n, rng):
    """The sampler isotropic models always used (kept here as the reference)."""
    if kind == "bounded":
        r = sigma * np.sqrt(rng.random(n))
        a = rng.random(n) * 2.0 * math.pi
        dxy = np.stack([r * np.cos(a), r * np.sin(a)], axis=1)
    else:
        dxy = rng.normal(scale=sigma * math.sqrt(2.0 / math.pi), size=(n, 2))
    dyaw = np.zeros(n)
    if yaw_sigma > 0.0:
        dyaw = np.round(rng.normal(scale=yaw_sigma, size=n) / YAW_LATTICE) * YAW_LATTICE
    return dxy, dyaw


@pytest.mark.parametrize("kind", ["gaussian", "bounded"])
@pytest.mark.parametrize("frame", ["base", "map"])
@pytest.mark.parametrize("yaw", [0.0, 1.3])
def test_an_isotropic_model_draws_what_it_always_drew(kind, frame, yaw):
    old = _old_sample(kind, 0.1, 0.02, 500, np.random.default_rng(7))
    new = ErrorDist(kind, 0.1, yaw_sigma=0.02, frame=frame).sample(
        500, np.random.default_rng(7), yaw
    )
    assert np.array_equal(old[0], new[0]) and np.array_equal(old[1], new[1])


@pytest.mark.parametrize("yaw", [0.0, 0.7, -2.4])
def test_a_base_frame_model_turns_with_the_stop(yaw):
    dxy, dyaw = ANISO.sample(200_000, np.random.default_rng(1), yaw)
    R = rot(yaw)
    assert dxy.mean(0) == pytest.approx(R @ np.array(ANISO.mean), abs=4e-4)
    assert np.cov(dxy.T) == pytest.approx(R @ ANISO.cov() @ R.T, abs=2e-5)
    assert dyaw.mean() == pytest.approx(ANISO.yaw_mean, abs=2e-4)
    assert dyaw.std() == pytest.approx(ANISO.yaw_sigma, rel=0.01)
    k = dyaw / YAW_LATTICE
    assert np.allclose(k, np.round(k))
    mu, C = ANISO.in_map(yaw)
    assert (
        mu == pytest.approx(R @ np.array(ANISO.mean)) and pytest.approx(R @ ANISO.cov() @ R.T) == C
    )
    fixed = ErrorDist("gaussian", mean=ANISO.mean, covariance=ANISO.covariance, frame="map")
    assert fixed.sample(50_000, np.random.default_rng(2), yaw)[0].mean(0) == pytest.approx(
        ANISO.mean, abs=5e-4
    )


def test_the_density_is_the_gaussian_and_integrates_to_one():
    from scipy.stats import multivariate_normal

    yaw = 0.4
    mu, C = ANISO.in_map(yaw)
    pts = np.random.default_rng(3).normal(size=(50, 2)) * 0.05
    assert ANISO.density(pts, yaw) == pytest.approx(multivariate_normal(mu, C).pdf(pts), rel=1e-9)
    g = np.linspace(-0.3, 0.3, 601)
    X, Y = np.meshgrid(g, g)
    total = ANISO.density(np.stack([X.ravel(), Y.ravel()], 1), yaw).sum() * (g[1] - g[0]) ** 2
    assert total == pytest.approx(1.0, abs=1e-4)
    b = ErrorDist("bounded", 0.1, mean=(0.05, 0.0))
    assert b.density(np.array([[0.14, 0.0], [0.16, 0.0]]), 0.0) == pytest.approx(
        [1 / (math.pi * 0.01), 0.0]
    )


@settings(max_examples=30, deadline=None)
@given(
    mx=st.floats(-0.15, 0.15), my=st.floats(-0.15, 0.15),
    sx=st.floats(0.005, 0.1), sy=st.floats(0.005, 0.1), rho=st.floats(-0.9, 0.9),
    r=st.floats(0.01, 0.3),
)  # fmt: skip
def test_disc_probability_against_sampling(mx, my, sx, sy, rho, r):
    c = rho * sx * sy
    d = ErrorDist("gaussian", mean=(mx, my), covariance=((sx * sx, c), (c, sy * sy)))
    dxy, _ = d.sample(40_000, np.random.default_rng(5))
    mc = (np.linalg.norm(dxy, axis=1) <= r).mean()
    assert d.disc_probability(r) == pytest.approx(mc, abs=4 * math.sqrt(0.25 / 40_000) + 2e-3)


@pytest.mark.parametrize("offset", [0.0, 0.04, 0.15, 0.3])
def test_a_biased_bounded_model_covers_the_lens(offset):
    d = ErrorDist("bounded", 0.1, mean=(offset, 0.0))
    dxy, _ = d.sample(100_000, np.random.default_rng(6))
    for r in (0.05, 0.12, 0.3):
        mc = (np.linalg.norm(dxy, axis=1) <= r).mean()
        assert d.disc_probability(r) == pytest.approx(mc, abs=0.006)


@pytest.mark.parametrize(
    "dist",
    [ANISO, ErrorDist("gaussian", 0.1), ErrorDist("bounded", 0.1, mean=(0.02, 0.03)),
     ErrorDist("bounded", 0.1), ErrorDist("gaussian", mean=(0.2, 0.0),
                                          covariance=((1e-4, 0.0), (0.0, 1e-4)))],
)  # fmt: skip
@pytest.mark.parametrize("target", [0.5, 0.9, 0.99])
def test_radius_for_inverts_the_disc_probability(dist, target):
    r = dist.radius_for(target)
    assert dist.disc_probability(r) == pytest.approx(target, abs=1e-6)
    assert dist.disc_probability(r * 0.98) < target


def test_the_first_station_holding_a_stop_applies():
    near = ErrorDist("gaussian", 0.02, name="aisle")
    shelf = ErrorDist("gaussian", 0.05, mean=(0.01, 0.0), name="shelf")
    pos = Positioning(
        ErrorDist("gaussian", 0.1),
        (
            Station("aisle", near, zone=((0, 0), (1, 0), (1, 1), (0, 1))),
            Station("shelf", shelf, trays=frozenset({"t2", "t3"})),
        ),
    )
    assert pos.at((0.5, 0.5), ["t2"]) is near  # the zone comes first
    assert pos.at((2.0, 0.5), ["t1", "t3"]) is shelf
    assert pos.at((2.0, 0.5), ["t1"]) is pos.default
    assert pos.station_of((2.0, 0.5), ["t1"]) is None
    assert pos.station_of((0.2, 0.2), []) == "aisle"
    assert pos.anisotropic and not Positioning(ErrorDist("bounded", 0.1)).anisotropic


def _five() -> dict:
    return json.loads((EXAMPLES / "five_trays.json").read_text())


def test_a_scene_with_station_models_and_its_unchanged_hash():
    from pickstop.sequence.request import scene_hash

    doc = _five()
    plain = parse_scene(doc)
    assert "mean" not in plain.model_dump()["error_model"]  # old scenes dump as they did
    trays = [t["id"] for t in doc["trays"]]
    doc["error_model"] = {
        "kind": "gaussian", "yaw_sigma": 0.01, "mean": [0.01, 0.0],
        "covariance": [[4e-4, 1e-4], [1e-4, 1e-4]],
        "stations": [
            {"name": "left", "trays": trays[:2], "sigma": 0.03, "yaw_mean": 0.01},
            {"name": "dock", "zone": [[0, 0], [1, 0], [1, 1]], "kind": "bounded"},
        ],
    }  # fmt: skip
    scene = parse_scene(doc)
    assert scene_hash(scene) != scene_hash(plain)
    pos = of_scene(scene)
    assert pos.default.covariance == ((4e-4, 1e-4), (1e-4, 1e-4))
    left = pos.at((9.0, 9.0), [trays[1]])
    assert (left.name, left.sigma, left.yaw_sigma, left.yaw_mean) == ("left", 0.03, 0.01, 0.01)
    dock = pos.at((0.6, 0.2), [])
    assert (dock.kind, dock.sigma) == ("bounded", scene.sigma)
    assert of_scene(scene, 0.2).at((0.6, 0.2), []).sigma == 0.2  # a plan's sigma option
    assert parse_scene(json.loads(scene.model_dump_json())) == scene


@pytest.mark.parametrize(
    ("change", "where"),
    [
        (lambda e: e.update(covariance=[[1e-4, 0.0], [1e-5, 1e-4]]), "symmetric"),
        (lambda e: e.update(covariance=[[1e-4, 2e-4], [2e-4, 1e-4]]), "positive definite"),
        (lambda e: e.update(kind="bounded", covariance=[[1e-4, 0], [0, 1e-4]]), "gaussian"),
        (lambda e: e.update(mean=[2.0, 0.0]), "error_model.mean.0"),
        (lambda e: e.update(stations=[{"name": "s"}]), "either trays"),
        (lambda e: e.update(stations=[{"name": "s", "trays": ["nope"]}]), "no tray nope"),
        (lambda e: e.update(stations=[{"name": "s", "zone": [[0, 0], [1, 1], [1, 0], [0, 1]]}]),
         "simple polygon"),
        (lambda e: e.update(stations=[{"name": "s", "zone": [[0, 0], [1, 0], [0, 1]]},
                                      {"name": "s", "zone": [[0, 0], [1, 0], [0, 1]]}]),
         "unique"),
    ],
)  # fmt: skip
def test_a_bad_error_model_is_refused_naming_it(change, where):
    doc = _five()
    em = copy.deepcopy(doc.get("error_model", {}))
    change(em)
    doc["error_model"] = em
    with pytest.raises(SceneError) as e:
        parse_scene(doc)
    assert where in e.value.message


def test_an_error_model_file_reads_with_or_without_a_scene():
    f = parse_error_file(
        {"format": "pickstop.error_model", "version": 1, "sigma": 0.04,
         "error_model": {"mean": [0.01, 0.02], "stations": [{"name": "a", "trays": ["x"]}]},
         "fit": {"anything": 1}}
    )  # fmt: skip
    pos = f.positioning()
    assert pos.default.sigma == 0.04 and pos.default.mean == (0.01, 0.02)
    assert pos.at((0, 0), ["x"]).name == "a"
    with pytest.raises(InputError) as e:
        parse_error_file({"error_model": {"covariance": [[1, 0], [0, -1]]}})
    assert e.value.field == "error_model.covariance"
