"""The open model from infants to elders (``age=<years>``): WHO statures, joints inside, adults untouched."""

from __future__ import annotations

import numpy as np
import pytest

import smplcore
from smplcore.measure import measure

# WHO stature-for-age medians (cm): WHO Child Growth Standards 2006 (ages 2-4, height) and WHO Growth
# Reference 2007 (ages 5-18, de Onis et al., Bull World Health Organ 85:660-667), rounded to 0.1 cm.
WHO_MEDIAN_CM = {
    "male": [
        87.1,
        96.1,
        103.3,
        110.0,
        116.0,
        121.7,
        127.3,
        132.6,
        137.8,
        143.1,
        149.1,
        156.0,
        163.2,
        169.0,
        172.9,
        175.2,
        176.1,
    ],
    "female": [
        85.7,
        95.1,
        102.7,
        109.4,
        115.1,
        120.8,
        126.6,
        132.5,
        138.6,
        144.9,
        151.2,
        156.4,
        159.8,
        161.7,
        162.5,
        162.9,
        163.1,
    ],
}
AGES = list(range(2, 19))


def _winding_numbers(vertices: np.ndarray, faces: np.ndarray, points: np.ndarray) -> np.ndarray:
    """Generalised winding number of each point (1 inside a closed outward mesh, 0 outside)."""
    out = []
    for p in points:
        a, b, c = (vertices[faces[:, k]] - p for k in range(3))
        la, lb, lc = (np.linalg.norm(x, axis=1) for x in (a, b, c))
        det = np.einsum("ij,ij->i", a, np.cross(b, c))
        den = la * lb * lc + np.einsum("ij,ij->i", a, b) * lc + np.einsum("ij,ij->i", b, c) * la
        den += np.einsum("ij,ij->i", c, a) * lb
        out.append(np.sum(2 * np.arctan2(det, den)) / (4 * np.pi))
    return np.array(out)


@pytest.mark.parametrize("gender", ["male", "female"])
def test_statures_at_ages_2_to_18_are_within_3_percent_of_the_who_medians(gender):
    got = np.array(
        [
            measure(smplcore.BodyModel(model_type="open", gender=gender, age=a), names=["stature"])["stature"]
            for a in AGES
        ]
    )
    ref = np.array(WHO_MEDIAN_CM[gender]) / 100
    rel = np.abs(got / ref - 1)
    assert rel.max() < 0.03, dict(zip(AGES, np.round(rel * 100, 2)))
    assert np.all(np.diff(got) > 0)  # children grow


@pytest.mark.parametrize("gender", ["neutral", "male", "female"])
def test_joints_are_inside_the_mesh_at_every_age(gender):
    for age in (1, 2, 4, 8, 12, 16, 25, 60, 90):
        model = smplcore.BodyModel(model_type="open", gender=gender, age=age, dtype=np.float64)
        out = model(betas=np.zeros((1, 10)))
        w = _winding_numbers(out.vertices[0], model.faces, out.joints[0, :24])
        assert np.all(w > 0.5), (age, np.round(w, 2))


def test_the_adult_default_is_untouched_and_betas_scale_with_the_body():
    import smplcore.io.open_model as om

    with np.load(om.open_model_path("neutral")) as d:
        template = d["v_template"]
    adult = smplcore.BodyModel(model_type="open")
    rest = adult(betas=np.zeros((1, 10))).vertices[0]
    np.testing.assert_allclose(rest, template, atol=1e-6)  # the packaged file's template, as before
    same = smplcore.BodyModel(model_type="open", age="adult")(betas=np.zeros((1, 10))).vertices[0]
    np.testing.assert_array_equal(same, rest)
    kid = smplcore.BodyModel(model_type="open", age=5, dtype=np.float64)
    tall = measure(kid, np.eye(10)[0], names=["stature"])["stature"] - measure(kid, names=["stature"])["stature"]
    adult_tall = (
        measure(adult, np.eye(10)[0], names=["stature"])["stature"] - measure(adult, names=["stature"])["stature"]
    )
    assert 0.55 < tall / adult_tall < 0.75  # a 1.10 m child: beta 0 moves it about 1.10/1.69 as much


def test_ages_outside_the_axis_and_other_models_are_refused(fake_models):
    with pytest.raises(ValueError, match="age"):
        smplcore.BodyModel(model_type="open", age=120)
    with pytest.raises(ValueError, match="open model"):
        smplcore.BodyModel(fake_models["smpl_neutral_pkl"], age=7)


def test_demo_age_writes_a_child(tmp_path):
    from smplcore.demo import run_demo

    result = run_demo(tmp_path, poses=["t-pose"], betas=[0.0], render=False, texture=None, age=6)
    rows = [line.split()[1:4] for line in result.mesh_path.read_text().splitlines() if line.startswith("v ")]
    stature = np.ptp(np.array(rows, dtype=float)[:, 1])
    assert abs(stature / 1.156 - 1) < 0.03  # the mean of WHO's 6-year-old boys and girls, 115.6 cm


def test_create_takes_the_age_too():
    torch = pytest.importorskip("torch")
    module = smplcore.create(model_type="open", gender="female", age=7)
    numpy_model = smplcore.BodyModel(model_type="open", gender="female", age=7)
    got = module(betas=torch.zeros(1, 10)).vertices[0].detach().numpy()
    np.testing.assert_allclose(got, numpy_model(betas=np.zeros((1, 10))).vertices[0], atol=1e-5)
    np.testing.assert_allclose(module.rig.template, numpy_model.rig.template)


def test_a_childs_fit_starts_from_the_age_of_its_stature():
    from smplcore.measure import age_for_stature, fit_shape

    age = age_for_stature(1.20, "female")
    assert 6.5 < age < 7.5  # WHO: girls' median is 115.1 cm at 6 and 120.8 cm at 7
    kid = smplcore.BodyModel(model_type="open", gender="female", age=age)
    np.testing.assert_allclose(measure(kid, names=["stature"])["stature"], 1.20, atol=0.003)
    fit = fit_shape(kid, height=1.22, mass=24.0)
    assert abs(fit.residual["stature"]) < 0.005 and abs(fit.residual["mass"]) < 0.5
    with pytest.raises(ValueError, match="gender"):
        age_for_stature(1.2, "child")
