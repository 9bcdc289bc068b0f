"""smplcore.join: FLAME heads joined to SMPL-X bodies and split off again, on the exact fakes.

The fake FLAME and SMPL-X files do not share geometry, so "bases that agree" are built here: a FLAME whose
expression basis *is* SMPL-X's on 5023 chosen vertices (the official ``SMPL-X__FLAME_vertex_ids.npy`` plays
that role for the real files), one whose basis is a mixed (rotated) version of it, and the unrelated fake.
"""

from __future__ import annotations

import numpy as np
import pytest

import smplcore
from smplcore.errors import ShapeError
from smplcore.join import FlameHead, expression_map, join_head, split_head
from smplcore.join.body import local_rotations, world_rotations
from smplcore.join.rotations import angle_between, to_axis_angle, to_matrix

E = 20  # expression coefficients used by both models here
CAMERA = to_matrix(np.array([0.2, 2.8, -0.1]))


@pytest.fixture(scope="module")
def models(fake_models):
    body_data = smplcore.load_model(fake_models["smplx_neutral_npz"])
    flame_data = smplcore.load_model(fake_models["flame_neutral_pkl"])
    body = smplcore.BodyModel(data=body_data, dtype=np.float64, num_expression_coeffs=E, use_pca=False)
    moved = np.linalg.norm(body_data.exprdirs, axis=(1, 2))
    ids = np.sort(np.argsort(-moved, kind="stable")[: flame_data.num_vertices])
    same = body_data.exprdirs[ids]
    rng = np.random.default_rng(11)
    q20 = rng.normal(size=(E, E)) + 3 * np.eye(E)  # invertible mix of the first 20 components
    mixed = same.copy()
    mixed[:, :, :E] = same[:, :, :E] @ q20

    def flame(exprdirs):
        data = flame_data if exprdirs is None else flame_data.replace(exprdirs=exprdirs)
        return smplcore.BodyModel(data=data, dtype=np.float64, num_expression_coeffs=E)

    return {
        "body": body,
        "ids": ids,
        "same": flame(same),
        "mixed": flame(mixed),
        "q20": q20,
        "unrelated": flame(None),
    }


def _body_params(rng, batch=2):
    return {
        "global_orient": rng.normal(0, 0.5, (batch, 3)),
        "body_pose": rng.normal(0, 0.3, (batch, 63)),
        "jaw_pose": rng.normal(0, 0.2, (batch, 3)),
        "leye_pose": rng.normal(0, 0.1, (batch, 3)),
        "reye_pose": rng.normal(0, 0.1, (batch, 3)),
        "expression": rng.normal(0, 1.0, (batch, E)),
        "betas": rng.normal(0, 1, (batch, 10)),
    }


def _headless(params):
    out = {k: v.copy() for k, v in params.items() if k not in ("jaw_pose", "leye_pose", "reye_pose", "expression")}
    out["body_pose"][:, 42:45] = 0.0  # the head joint (15) -> body_pose row 14
    return out


def _head_error(body, a, b):
    rig = body.rig
    la, lb = local_rotations(rig, a, 2), local_rotations(rig, b, 2)
    wa, wb = world_rotations(rig, la), world_rotations(rig, lb)
    joints = [rig.joint_names.index(n) for n in ("head", "jaw", "left_eye_smplhf", "right_eye_smplhf")]
    return float(angle_between(wa[:, joints], wb[:, joints]).max())


@pytest.mark.parametrize("flame_key", ["same", "mixed"])
@pytest.mark.parametrize("camera", [False, True])
def test_heads_split_then_joined_give_back_the_head(models, flame_key, camera):
    body, flame, ids = models["body"], models[flame_key], models["ids"]
    params = _body_params(np.random.default_rng(12))
    cam = CAMERA if camera else None
    head = split_head(body, params, flame, vertex_ids=ids, camera_rotation=cam)
    result = join_head(body, _headless(params), head, flame, vertex_ids=ids)
    assert _head_error(body, params, result.params) <= 1e-5
    np.testing.assert_allclose(result.params["expression"], params["expression"], atol=1e-8)
    va, vb = body(**params).vertices, body(**result.params).vertices
    assert np.linalg.norm(va - vb, axis=-1).max() <= 1e-5
    r = result.residuals["head"]
    assert r.direct is (flame_key == "same")
    assert r.max_angle <= 1e-5 and r.expression_rms.max() <= 1e-8


def test_flame_expression_is_copied_where_the_bases_agree_and_fitted_where_they_do_not(models):
    body, ids = models["body"], models["ids"]
    same = expression_map(models["same"], body, ids)
    assert same.direct and same.difference == 0.0
    np.testing.assert_array_equal(same.matrix, np.eye(E))
    mixed = expression_map(models["mixed"], body, ids)
    assert not mixed.direct and mixed.difference > 0.1
    np.testing.assert_allclose(mixed.matrix, models["q20"], atol=1e-8)  # e_body = Q e_flame, exactly
    back = expression_map(body, models["mixed"], ids)
    np.testing.assert_allclose(back.matrix @ mixed.matrix, np.eye(E), atol=1e-8)
    forced = expression_map(models["mixed"], body, ids, mode="direct")
    assert forced.direct and forced.difference > 0.1  # copying was asked for; the difference is still reported


def test_an_unrelated_flame_expression_gives_a_bounded_fit_residual(models):
    """The unrelated fake FLAME: its basis is not SMPL-X's, the fit is the least-squares one -- never worse than
    leaving the face neutral, and reported."""
    body, flame, ids = models["body"], models["unrelated"], models["ids"]
    rng = np.random.default_rng(13)
    expr = rng.normal(0, 1.0, (2, E))
    result = join_head(body, _headless(_body_params(rng)), FlameHead(expression=expr), flame, vertex_ids=ids)
    r = result.residuals["head"]
    assert not r.direct
    target = np.einsum("vck,bk->bvc", flame.rig.exprdirs, expr)
    neutral = np.sqrt(np.mean(np.sum(target**2, axis=-1), axis=-1))
    assert np.all(r.expression_rms > 0) and np.all(r.expression_rms <= neutral)
    # perturbing a matching FLAME's expression by delta moves the residual by at most |A delta|
    same = models["same"]
    noisy = join_head(body, _headless(_body_params(rng)), FlameHead(expression=expr + 0.01), same, vertex_ids=ids)
    assert noisy.residuals["head"].expression_rms.max() <= 1e-10  # an agreeing basis holds any expression


def test_flame_orientation_in_the_camera_frame_sets_the_head_joint(models):
    body = models["body"]
    rng = np.random.default_rng(14)
    params = _body_params(rng, batch=1)
    rig = body.rig
    head_world = to_matrix(rng.normal(0, 0.7, (1, 3)))
    flame = FlameHead(global_orient=to_axis_angle(CAMERA @ head_world), camera_rotation=CAMERA)
    result = join_head(body, params, flame, expression="direct")
    world = world_rotations(rig, local_rotations(rig, result.params, 1))
    assert angle_between(world[:, rig.joint_names.index("head")], head_world).max() <= 1e-9
    assert np.all(np.isnan(result.residuals["head"].expression_rms))
    assert "expression" not in result.params or np.array_equal(result.params["expression"], params["expression"])


def test_the_split_head_is_what_flame_takes(models):
    """Posed by the FLAME model, the split head's root joint sits on SMPL-X's neck joint and its neck joint has
    SMPL-X's head orientation; jaw and eyes carry their local rotations (camera frame included)."""
    body, flame = models["body"], models["same"]
    params = _body_params(np.random.default_rng(17))
    params["transl"] = np.array([[0.1, -0.2, 0.3]])
    t = np.array([0.0, 0.1, 2.0])
    head = split_head(body, params, flame, vertex_ids=models["ids"], camera_rotation=CAMERA, camera_translation=t)
    out = flame(
        global_orient=head.global_orient,
        neck_pose=head.neck_pose,
        jaw_pose=head.jaw_pose,
        leye_pose=head.leye_pose,
        reye_pose=head.reye_pose,
        betas=head.betas,
        transl=head.transl,
        expression=head.expression,
    )
    rig = body.rig
    neck, head_joint = rig.joint_names.index("neck"), rig.joint_names.index("head")
    body_out = body(**params)
    np.testing.assert_allclose(out.joints[:, 0], body_out.joints[:, neck] @ CAMERA.T + t, atol=1e-9)
    world = world_rotations(rig, local_rotations(rig, params, 2))
    flame_head = out.rotmats[:, 0] @ out.rotmats[:, 1]
    assert angle_between(flame_head, CAMERA @ world[:, head_joint]).max() <= 1e-9


def test_join_head_refuses_wrong_inputs(models, fake_models):
    body, flame, ids = models["body"], models["same"], models["ids"]
    with pytest.raises(ValueError, match="vertex_ids: mode='auto' needs"):
        join_head(body, {}, FlameHead(expression=np.zeros((1, E))), flame)
    with pytest.raises(ValueError, match="flame_model: mapping"):
        join_head(body, {}, FlameHead(expression=np.zeros((1, E))))
    with pytest.raises(ShapeError, match=r"vertex_ids: expected \(5023,\)"):
        join_head(body, {}, FlameHead(expression=np.zeros((1, E))), flame, vertex_ids=ids[:10])
    with pytest.raises(ShapeError, match=r"head.expression: expected \(B, 20\)"):
        join_head(body, {}, FlameHead(expression=np.zeros((1, 7))), flame, vertex_ids=ids)
    with pytest.raises(ValueError, match="expected an SMPL-X model"):
        join_head(flame, {}, FlameHead())
    with pytest.raises(ValueError, match="mode: expected"):
        expression_map(flame, body, ids, mode="closest")
