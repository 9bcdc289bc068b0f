"""smplcore.measure.fit_shape: shapes from measurements (round trip, published adult targets, bounds, errors)."""

from __future__ import annotations

import numpy as np
import pytest

import smplcore
from smplcore.measure import fit_shape, measure

# ANSUR II men (C. C. Gordon et al., "2012 Anthropometric Survey of U.S. Army Personnel: Methods and Summary
# Statistics", NATICK/TR-15/007, 2014): means and SDs of stature, weight and waist circumference (omphalion),
# rounded. The correlations between them are our assumption (typical of adult surveys), not ANSUR's.
ANSUR_II_MEN = {"stature": (1.756, 0.069), "mass": (85.5, 14.2), "waist": (0.941, 0.112)}
CORRELATION = np.array([[1.0, 0.45, 0.20], [0.45, 1.0, 0.85], [0.20, 0.85, 1.0]])


@pytest.fixture(scope="module")
def male():
    return smplcore.BodyModel(model_type="open", gender="male", dtype=np.float64)


def test_round_trip_betas_to_measurements_to_betas(male):
    truth = np.array([0.8, -0.6, 0.5, 0.0])
    names = ["stature", "mass", "waist", "hip"]
    targets = measure(male, truth, names=names)
    fit = fit_shape(male, num_betas=4, prior=0.0, **targets)
    np.testing.assert_allclose(fit.betas[:4], truth, atol=0.05)  # 4 measurements fix 4 betas
    assert np.all(fit.betas[4:] == 0)
    assert abs(fit.residual["stature"]) < 1e-3 and abs(fit.residual["waist"]) < 2e-3
    again = measure(male, fit.betas, names=names)
    for n in names:
        np.testing.assert_allclose(again[n], fit.measured[n])


def test_random_ansur_ii_men_are_reached_within_5_mm_and_1_cm_for_95_percent():
    male = smplcore.BodyModel(model_type="open", gender="male", dtype=np.float64, num_betas=16)  # all it has
    rng = np.random.default_rng(7)
    z = rng.multivariate_normal(np.zeros(3), CORRELATION, size=20)
    targets = {n: mu + sd * z[:, i] for i, (n, (mu, sd)) in enumerate(ANSUR_II_MEN.items())}
    fit = fit_shape(male, **targets)
    assert fit.betas.shape == (20, 16)
    ok = (np.abs(fit.residual["stature"]) <= 0.005) & (np.abs(fit.residual["waist"]) <= 0.01)
    assert ok.mean() >= 0.95, (ok.mean(), fit.residual)
    assert np.median(np.abs(fit.residual["mass"])) < 0.5
    assert np.all(np.abs(fit.betas) <= 3.0 + 1e-9)


def test_bounds_and_weights_are_honoured(male):
    fit = fit_shape(male, height=2.3, bounds=1.0)  # out of reach within one SD: stops at the bound
    assert np.all(np.abs(fit.betas) <= 1.0 + 1e-9) and fit.residual["stature"] < -0.1
    both = {"height": 1.80, "waist": 0.70}  # a tall, very thin man: the two cannot both be met
    tall = fit_shape(male, weights={"height": 100.0}, **both)
    thin = fit_shape(male, weights={"waist": 100.0}, **both)
    assert abs(tall.residual["stature"]) < abs(thin.residual["stature"])
    assert abs(thin.residual["waist"]) < abs(tall.residual["waist"])


def test_bad_targets_raise_errors_that_name_them(male):
    with pytest.raises(ValueError, match="armspan"):
        fit_shape(male, armspan=1.7)
    with pytest.raises(ValueError, match="at least one"):
        fit_shape(male)
    with pytest.raises(ValueError, match="waist"):
        fit_shape(male, height=[1.7, 1.8], waist=[0.8, 0.9, 1.0])
    with pytest.raises(ValueError, match="mass"):
        fit_shape(male, mass=float("nan"))
    with pytest.raises(ValueError, match="not both"):
        fit_shape(male, height=1.7, stature=1.8)
