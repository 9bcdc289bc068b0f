"""smplcore.measure: girths and volumes against closed-form solids, and plausible bodies from the open model."""

from __future__ import annotations

import numpy as np
import pytest

import smplcore
from smplcore.family.names import SMPL_JOINTS
from smplcore.measure import MEASUREMENTS, measure, measure_mesh
from smplcore.measure.api import rest_body
from smplcore.measure.definitions import measure_body
from smplcore.measure.geometry import hull_girth, pick_loop, section, topology, volume

UP = np.array([0.0, 1.0, 0.0])


def _cylinder(radius: float, height: float, sections: int = 128, rings: int = 8, capped: bool = True):
    """A closed (or open-topped) cylinder along +Y, its base at y = 0."""
    ang = 2 * np.pi * np.arange(sections) / sections
    ring = np.stack([radius * np.cos(ang), np.zeros(sections), -radius * np.sin(ang)], axis=1)
    verts = [ring + [0.0, height * k / rings, 0.0] for k in range(rings + 1)]
    v = np.concatenate(verts + [np.array([[0.0, 0.0, 0.0], [0.0, height, 0.0]])])
    faces = []
    for k in range(rings):
        for i in range(sections):
            a, b = k * sections + i, k * sections + (i + 1) % sections
            c, d = a + sections, b + sections
            faces += [[a, b, d], [a, d, c]]
    bottom, top = len(v) - 2, len(v) - 1
    for i in range(sections):
        faces.append([bottom, (i + 1) % sections, i])
        if capped:
            faces.append([top, rings * sections + i, rings * sections + (i + 1) % sections])
    return v, np.array(faces)


def _ellipsoid(a: float, b: float, c: float, n: int = 96):
    """A UV ellipsoid with semi-axes a (x), b (y), c (z)."""
    th = np.linspace(0, np.pi, n + 1)[1:-1]
    ph = 2 * np.pi * np.arange(2 * n) / (2 * n)
    tt, pp = np.meshgrid(th, ph, indexing="ij")
    v = np.stack([a * np.sin(tt) * np.cos(pp), b * np.cos(tt), -c * np.sin(tt) * np.sin(pp)], -1).reshape(-1, 3)
    v = np.concatenate([v, [[0, b, 0], [0, -b, 0]]])
    m = 2 * n
    faces = []
    for i in range(len(th) - 1):
        for j in range(m):
            p, q = i * m + j, i * m + (j + 1) % m
            faces += [[p, q, q + m], [p, q + m, p + m]]
    top, bot = len(v) - 2, len(v) - 1
    last = (len(th) - 1) * m
    for j in range(m):
        faces.append([top, (j + 1) % m, j])
        faces.append([bot, last + j, last + (j + 1) % m])
    return v, np.array(faces)[:, ::-1]  # wound outwards


def test_cylinder_girth_and_volume_match_the_closed_form_within_one_percent():
    r, h = 0.15, 0.9
    v, f = _cylinder(r, h)
    topo = topology(f)
    assert topo.num_holes == 0
    loop = pick_loop(section(v, topo, np.array([0.0, 0.37, 0.0]), UP), np.zeros(3), UP)
    girth = hull_girth(loop, topo, UP).value
    assert abs(girth / (2 * np.pi * r) - 1) < 0.01
    assert abs(volume(v, topo).value / (np.pi * r * r * h) - 1) < 0.01


def test_ellipsoid_girth_and_volume_match_the_closed_form_within_one_percent():
    a, b, c = 0.16, 0.5, 0.11
    v, f = _ellipsoid(a, b, c)
    topo = topology(f)
    loop = pick_loop(section(v, topo, np.zeros(3), UP), np.zeros(3), UP)
    h = ((a - c) / (a + c)) ** 2
    ramanujan = np.pi * (a + c) * (1 + 3 * h / (10 + np.sqrt(4 - 3 * h)))
    assert abs(hull_girth(loop, topo, UP).value / ramanujan - 1) < 0.01
    assert abs(volume(v, topo).value / (4 / 3 * np.pi * a * b * c) - 1) < 0.01


def test_open_meshes_are_closed_by_fans_before_the_volume():
    r, h = 0.2, 1.0
    closed = volume(*_prepared(_cylinder(r, h, capped=True)))
    v, f = _cylinder(r, h, capped=False)
    topo = topology(f)
    assert topo.num_holes == 1
    np.testing.assert_allclose(volume(v, topo).value, closed.value, rtol=1e-9)


def _prepared(mesh):
    v, f = mesh
    return v, topology(f)


def test_girth_is_a_tape_over_concave_parts_and_picks_the_loop_around_the_point():
    # a star-shaped prism: the tape spans the concave notches (convex hull), and a second prism next to it
    # is a separate loop that is not measured
    k = 10
    ang = 2 * np.pi * np.arange(2 * k) / (2 * k)
    rad = np.where(np.arange(2 * k) % 2 == 0, 0.1, 0.05)
    ring = np.stack([rad * np.cos(ang), np.zeros(2 * k), -rad * np.sin(ang)], 1)
    v = np.concatenate([ring, ring + [0, 1, 0]])
    n = 2 * k
    f = [[i, (i + 1) % n, (i + 1) % n + n] for i in range(n)] + [[i, (i + 1) % n + n, i + n] for i in range(n)]
    v2, f2 = _cylinder(0.05, 1.0)
    v = np.concatenate([v, v2 + [0.5, 0, 0]])
    f = np.concatenate([np.array(f), f2 + 2 * n])
    topo = topology(f)
    loops = section(v, topo, np.array([0.0, 0.5, 0.0]), UP)
    assert len(loops) == 2
    star = pick_loop(loops, np.zeros(3), UP)
    tips = ring[::2]
    expected = np.sum(np.linalg.norm(tips - np.roll(tips, 1, axis=0), axis=1))
    np.testing.assert_allclose(hull_girth(star, topo, UP).value, expected, rtol=1e-9)
    other = pick_loop(loops, np.array([0.5, 0.5, 0.0]), UP)
    assert abs(hull_girth(other, topo, UP).value - 2 * np.pi * 0.05) < 0.003


@pytest.fixture(scope="module", params=["neutral", "male", "female"])
def open_model(request):
    return smplcore.BodyModel(model_type="open", gender=request.param)


def test_the_open_models_mean_bodies_are_plausible_adults(open_model):
    m = measure(open_model)
    assert set(m) == set(MEASUREMENTS)
    v = open_model().vertices[0]
    np.testing.assert_allclose(m["stature"], np.ptp(v[:, 1]), rtol=1e-5)
    assert 1.55 < m["stature"] < 1.85 and 50 < m["mass"] < 90
    # tools/build_open_model.py drew BMI around 24.2 (men) / 24.4 (women) kg/m^2 with the same density
    assert abs(m["bmi"] - 24.3) < 1.0
    assert m["waist"] < m["hip"] and m["waist"] < m["chest"] and m["under_bust"] <= m["chest"]
    assert 0.60 < m["waist"] < 1.0 and 0.85 < m["hip"] < 1.15 and 0.85 < m["chest"] < 1.2
    assert 0.45 < m["thigh"] < 0.70 and 0.30 < m["calf"] < 0.45 and 0.24 < m["upper_arm"] < 0.36
    assert 0.30 < m["neck"] < 0.42 and 0.28 < m["shoulder_breadth"] < 0.45
    assert 0.42 < m["inseam"] / m["stature"] < 0.50 and 0.50 < m["sitting_height"] / m["stature"] < 0.56
    np.testing.assert_allclose(m["inseam"] + m["sitting_height"], m["stature"], rtol=1e-9)
    assert 0.40 < m["arm_length"] < 0.65
    np.testing.assert_allclose(m["bmi"], m["mass"] / m["stature"] ** 2)


def test_taller_and_heavier_betas_measure_taller_and_heavier():
    model = smplcore.BodyModel(model_type="open")
    batch = measure(model, np.array([[-2.0], [0.0], [2.0]]), names=["stature", "mass", "waist"])
    assert np.all(np.diff(batch["stature"]) > 0.05) and np.all(np.diff(batch["mass"]) > 5)
    single = measure(model, np.array([2.0] + [0.0] * 9), names=["stature", "mass", "waist"])
    for k in single:
        np.testing.assert_allclose(batch[k][2], single[k])


def test_a_mesh_with_its_joints_measures_like_the_model():
    model = smplcore.BodyModel(model_type="open", dtype=np.float64)
    betas = np.linspace(-1, 1, 10)
    out = model(betas=betas[None])
    from_mesh = measure_mesh(out.vertices[0], model.faces, out.joints[0, :24])
    from_model = measure(model, betas)
    for k in MEASUREMENTS:
        np.testing.assert_allclose(from_mesh[k], from_model[k], rtol=1e-6, atol=1e-9)


def test_trunk_and_right_limb_measurements_do_not_move_when_the_left_arm_and_leg_bend():
    model = smplcore.BodyModel(model_type="open", dtype=np.float64)
    pose = np.zeros((23, 3))
    pose[SMPL_JOINTS.index("left_elbow") - 1] = (0.0, 1.2, 0.0)
    pose[SMPL_JOINTS.index("left_knee") - 1] = (0.9, 0.0, 0.0)
    names = ["waist", "hip", "chest", "neck", "calf", "thigh", "upper_arm", "stature"]
    rest = measure(model, np.zeros(10), names=names)
    posed = measure(model, np.zeros(10), names=names, body_pose=pose.reshape(-1))
    for k in names:
        np.testing.assert_allclose(posed[k], rest[k], rtol=1e-6)


def test_gradients_match_finite_differences_through_the_shape_basis():
    model = smplcore.BodyModel(model_type="open", dtype=np.float64)
    names = ["stature", "mass", "inseam", "arm_length"]
    beta = np.full(10, 0.3)
    body = rest_body(model, beta)
    lins = measure_body(body, names)
    dirs = model.rig.shapedirs
    for k in range(3):
        step = np.zeros(10)
        step[k] = 1e-4
        plus = measure_body(rest_body(model, beta + step), names)
        for n in names:
            numeric = (plus[n].value - lins[n].value) / 1e-4
            analytic = np.einsum("kc,kc->", lins[n].weights, dirs[lins[n].rows, :, k])
            assert abs(numeric - analytic) <= 2e-3 * max(1.0, abs(numeric)), (n, k, numeric, analytic)


def test_unknown_names_and_bad_joints_raise_errors_that_name_them():
    model = smplcore.BodyModel(model_type="open")
    with pytest.raises(ValueError, match="bust_point"):
        measure(model, names=["bust_point"])
    v, f = _cylinder(0.1, 1.0)
    with pytest.raises(ValueError, match="joints"):
        measure_mesh(v, f, {"pelvis": np.zeros(3)})


@pytest.mark.parametrize("key", ["smpl_neutral_pkl", "smplh_neutral_pkl", "smplx_neutral_npz"])
def test_every_body_model_of_the_family_is_measured_through_both_front_ends(fake_models, key):
    torch = pytest.importorskip("torch")
    names = ["stature", "mass", "waist", "calf", "inseam", "upper_arm"]
    numpy_model = smplcore.BodyModel(fake_models[key], dtype=np.float64)
    got = measure(numpy_model, names=names)
    assert all(np.isfinite(v) and v > 0 for v in got.values())
    module = smplcore.create(fake_models[key], dtype=torch.float64)
    from_torch = measure(module, names=names)
    for k in names:
        np.testing.assert_allclose(from_torch[k], got[k], rtol=1e-9)
