"""smplcore.join: MANO hands joined to SMPL-X / SMPL+H bodies and split off again, on the exact fakes.

The fake MANO and SMPL-X files do not share geometry (random data), but they share what joining relies on:
the hands' joint order and rest frames (identity), and the hand PCA (SMPL-X's hand PCA is MANO's, in the
fakes as in the official files). So the proofs compare rotations, and the body model's own vertices.
"""

from __future__ import annotations

import itertools

import numpy as np
import pytest

import smplcore
from smplcore.errors import ShapeError
from smplcore.join import ManoHand, fixed_left_shapedirs, join_hands, left_shapedirs_flipped, split_hands
from smplcore.join.rotations import angle_between, mirror_matrix, to_axis_angle, to_matrix

ROT_TOL = 1e-5  # rad
VERT_TOL = 1e-5  # m
CAMERA = to_matrix(np.array([0.4, -2.5, 0.3]))  # world -> camera
CAMERA_T = np.array([0.05, -0.1, 2.5])


@pytest.fixture(scope="module")
def data(fake_models):
    return {
        "smplx": smplcore.load_model(fake_models["smplx_neutral_npz"]),
        "smplh": smplcore.load_model(fake_models["smplh_neutral_pkl"]),
    }


@pytest.fixture(scope="module")
def bodies(data):
    """Body models per (model type, use_pca, flat_hand_mean), float64."""
    cache = {}

    def get(kind="smplx", use_pca=False, flat=False, comps=6):
        key = (kind, use_pca, flat, comps)
        if key not in cache:
            cache[key] = smplcore.BodyModel(
                data=data[kind], dtype=np.float64, use_pca=use_pca, num_pca_comps=comps, flat_hand_mean=flat
            )
        return cache[key]

    return get


@pytest.fixture(scope="module")
def manos(fake_models):
    cache = {}

    def get(side, use_pca=False, flat=True, comps=12):
        key = (side, use_pca, flat, comps)
        if key not in cache:
            cache[key] = smplcore.BodyModel(
                fake_models[f"mano_{side}_pkl"],
                dtype=np.float64,
                use_pca=use_pca,
                num_pca_comps=comps,
                flat_hand_mean=flat,
            )
        return cache[key]

    return get


def _posed_params(body, rng, batch=2, hand_scale=0.6, about_mean=True):
    """Random body parameters whose hand poses lie in the first 6 PCA directions of the file about the mean
    hand (``about_mean``) or about the flat hand, written in ``body``'s convention; plus the absolute finger
    axis-angle per side. (A PCA space about the mean holds the first, one about the flat hand the second.)"""
    rig = body.rig
    spaces = _SPACES[id(body)]
    params = {
        "global_orient": rng.normal(0, 0.6, (batch, 3)),
        "body_pose": rng.normal(0, 0.35, (batch, 63)),
        "betas": rng.normal(0, 1, (batch, 10)),
        "transl": rng.normal(0, 0.5, (batch, 3)),
    }
    absolute = {}
    for side in ("left", "right"):
        comps, mean = spaces[side]
        coeffs = rng.normal(0, hand_scale, (batch, 6))
        absolute[side] = coeffs @ comps[:6] + (mean if about_mean else 0.0)
        name = f"{side}_hand_pose"
        if name in rig.hand_components:
            params[name] = np.linalg.lstsq(
                rig.hand_components[name].T, (absolute[side] - rig.hand_means[name]).T, rcond=None
            )[0].T
        else:
            params[name] = absolute[side] - rig.hand_means[name]
    return params, absolute


_SPACES: dict = {}


@pytest.fixture(scope="module")
def body_of(bodies, data):
    def get(kind="smplx", use_pca=False, flat=False):
        body = bodies(kind, use_pca, flat)
        if id(body) not in _SPACES:
            pca = smplcore.BodyModel(
                data=data[kind], dtype=np.float64, use_pca=True, num_pca_comps=12, flat_hand_mean=False
            )
            rig = pca.rig
            _SPACES[id(body)] = {
                s: (rig.hand_components[f"{s}_hand_pose"], rig.hand_means[f"{s}_hand_pose"]) for s in ("left", "right")
            }
        return body

    return get


def _without_hands(params):
    """The body with its wrists and hands reset (what a body estimator without hands gives)."""
    out = {k: v.copy() for k, v in params.items() if not k.endswith("hand_pose")}
    out["body_pose"][:, 57:63] = 0.0  # left_wrist (20), right_wrist (21): joints 20, 21 -> rows 19, 20
    return out


def _wrist_and_finger_error(body, a, b):
    """Largest rotation angle between two parameter sets over both wrists' world rotations and all finger joints."""
    from smplcore.join.body import local_rotations, world_rotations

    rig = body.rig
    batch = a["body_pose"].shape[0]
    la, lb = local_rotations(rig, a, batch), local_rotations(rig, b, batch)
    wa, wb = world_rotations(rig, la), world_rotations(rig, lb)
    wrists = [rig.joint_names.index(f"{s}_wrist") for s in ("left", "right")]
    fingers = [
        i for i, n in enumerate(rig.joint_names) if n[:-1].endswith(("index", "middle", "pinky", "ring", "thumb"))
    ]
    assert len(fingers) == 30
    return max(
        float(angle_between(wa[:, wrists], wb[:, wrists]).max()),
        float(angle_between(la[:, fingers], lb[:, fingers]).max()),
    )


def _hand_vertex_error(body, a, b, threshold=0.5):
    """Largest distance between the body's hand vertices (wrist and finger weights summing over ``threshold``)
    for two parameter sets."""
    rig = body.rig
    hand_joints = [
        i
        for i, n in enumerate(rig.joint_names)
        if n.endswith("wrist") or n[:-1].endswith(("index", "middle", "pinky", "ring", "thumb"))
    ]
    mask = rig.weights[:, hand_joints].sum(axis=1) > threshold
    assert mask.sum() > 100
    va, vb = body(**a).vertices, body(**b).vertices
    return float(np.linalg.norm(va[:, mask] - vb[:, mask], axis=-1).max())


# the MANO conventions: (label, builder of split_hands' keywords from the manos fixture)
MANO_CONVENTIONS = {
    "full-flat": lambda manos, mirror: {"flat_hand_mean": True},
    "full-mean": lambda manos, mirror: {"flat_hand_mean": False},
    "model-full-flat": lambda manos, mirror: {
        "hand_models": {"left": manos("right" if mirror else "left"), "right": manos("right")}
    },
    "model-pca-mean": lambda manos, mirror: {
        "hand_models": {"left": manos("right" if mirror else "left", True, False), "right": manos("right", True, False)}
    },
    "model-pca-flat": lambda manos, mirror: {
        "hand_models": {"left": manos("right" if mirror else "left", True, True), "right": manos("right", True, True)}
    },
}
BODY_CONVENTIONS = [
    ("smplx", False, False),
    ("smplx", False, True),
    ("smplx", True, False),
    ("smplx", True, True),
    ("smplh", False, False),
]


@pytest.mark.parametrize("body_key", BODY_CONVENTIONS, ids=lambda k: "-".join(map(str, k)))
@pytest.mark.parametrize("mano_key", list(MANO_CONVENTIONS))
@pytest.mark.parametrize("mirror,camera", list(itertools.product([False, True], [False, True])))
def test_hands_split_then_joined_give_back_the_wrists_and_fingers(body_of, manos, body_key, mano_key, mirror, camera):
    kind, use_pca, flat = body_key
    body = body_of(kind, use_pca, flat)
    if mano_key == "full-mean" and flat:
        pytest.skip("a flat body model has no mean hand pose to write MANO's mean-relative pose against")
    spaces = ([not flat] if use_pca else []) + ([mano_key == "model-pca-mean"] if "pca" in mano_key else [])
    if len(set(spaces)) > 1:
        pytest.skip("PCA spaces about different means cannot hold each other's poses (test_pca_spaces_about_...)")
    rng = np.random.default_rng(hash((body_key, mano_key, mirror, camera)) % 2**32)
    params, _ = _posed_params(body, rng, about_mean=spaces[0] if spaces else True)
    kwargs = MANO_CONVENTIONS[mano_key](manos, mirror)
    if camera:
        kwargs.update(camera_rotation=CAMERA, camera_translation=CAMERA_T)
    hands = split_hands(body, params, mirror_left=mirror, **kwargs)
    assert hands["left"].mirrored is mirror and hands["right"].mirrored is False
    result = join_hands(body, _without_hands(params), left=hands["left"], right=hands["right"])
    joined = result.params
    assert _wrist_and_finger_error(body, params, joined) <= ROT_TOL
    assert _hand_vertex_error(body, params, joined) <= VERT_TOL
    np.testing.assert_allclose(
        joined["body_pose"][:, :57], params["body_pose"][:, :57], atol=1e-12
    )  # the rest untouched
    for side in ("left", "right"):
        r = result.residuals[side]
        assert r.wrist_angle.max() <= ROT_TOL and r.finger_angle.max() <= ROT_TOL and r.pca_residual.max() <= 1e-9
        if "model" in mano_key:  # MANO's wrist placed on the body's, read back through mirror and camera
            assert r.wrist_offset is not None and r.wrist_offset.max() <= VERT_TOL
        else:
            assert r.wrist_offset is None


def test_pca_spaces_about_different_means_lose_what_they_cannot_hold_and_say_so(body_of, manos):
    """A flat 6-component body hand is not in MANO's 12-component space about the mean hand: the split warns
    with the size of the loss, and joining the lossy MANO hand back reports it as the finger residual."""
    body = body_of("smplx", True, True)
    params, _ = _posed_params(body, np.random.default_rng(9), about_mean=False)
    with pytest.warns(UserWarning, match=r"outside hand_models\['left'\]'s 12-component PCA space by up to"):
        hands = split_hands(body, params, hand_models={"left": manos("left", True, False), "right": manos("right")})
    result = join_hands(body, _without_hands(params), **hands)
    lost = result.residuals["left"]
    assert np.all(lost.finger_angle > 1e-3) and np.all(lost.finger_angle < 1.0)
    assert result.residuals["right"].max_angle <= ROT_TOL  # full MANO pose: nothing lost


def test_the_hand_parameters_are_what_mano_takes(body_of, manos):
    """The split hand posed by the MANO model has the body's hand orientation and finger rotations, and its
    wrist sits on the body's wrist (zero MANO betas): the parameters are usable by a hand-only tool."""
    body = body_of("smplx", False, False)
    params, absolute = _posed_params(body, np.random.default_rng(3))
    hands = split_hands(body, params, hand_models={"left": manos("left", True, False), "right": manos("right")})
    out = body(**params)
    names = body.skeleton_joint_names
    rig = body.rig
    from smplcore.join.body import local_rotations, world_rotations

    world = world_rotations(rig, local_rotations(rig, params, 2))
    for side in ("left", "right"):
        hand = hands[side]
        mano = hand.model
        mano_out = mano(
            global_orient=hand.global_orient, hand_pose=hand.hand_pose, betas=hand.betas, transl=hand.transl
        )
        wrist = names.index(f"{side}_wrist")
        np.testing.assert_allclose(mano_out.joints[:, 0], out.joints[:, wrist], atol=1e-9)
        assert angle_between(mano_out.rotmats[:, 0], world[:, wrist]).max() <= 1e-9
        assert angle_between(mano_out.rotmats[:, 1:], to_matrix(absolute[side].reshape(2, 15, 3))).max() <= 1e-9


def test_a_hamer_like_left_hand_is_the_mirror_of_the_body_hand(body_of, manos):
    """HaMeR / WiLoR's left hand: right-MANO rotation matrices of the flipped crop, in the camera frame. The
    right model posed with them, mirrored back (x -> -x in the camera), is the left hand seen by the camera."""
    body = body_of("smplx", False, True)
    params, absolute = _posed_params(body, np.random.default_rng(4), batch=1, about_mean=False)
    hands = split_hands(body, params, mirror_left=True, camera_rotation=CAMERA)
    left = hands["left"]
    go, hp = to_matrix(left.global_orient)[:, None], to_matrix(left.hand_pose.reshape(1, 15, 3))
    hamer_like = ManoHand(global_orient=go, hand_pose=hp, mirrored=True, camera_rotation=CAMERA)
    result = join_hands(body, _without_hands(params), left=hamer_like, right=hands["right"])
    assert _wrist_and_finger_error(body, params, result.params) <= ROT_TOL
    rig = body.rig
    from smplcore.join.body import local_rotations, world_rotations

    world = world_rotations(rig, local_rotations(rig, params, 1))
    # the mirrored right hand's orientation, mirrored in the camera frame and taken to the world, is the left wrist
    wrist = rig.joint_names.index("left_wrist")
    assert angle_between(CAMERA.T @ mirror_matrix(go[:, 0]), world[:, wrist]).max() <= 1e-9


def test_perturbed_hands_give_bounded_residuals(body_of, manos):
    """Noise a body's 6-component PCA cannot hold is reported (pca_residual = the part left out, finger
    angles of its size), a perturbed orientation moves the wrist by exactly the perturbation, a perturbed
    MANO translation shows as the wrist offset."""
    body = body_of("smplx", True, False)
    rng = np.random.default_rng(5)
    params, _ = _posed_params(body, rng)
    hands = split_hands(body, params, hand_models={"left": manos("left"), "right": manos("right")})
    noise = rng.normal(0, 0.02, (2, 45))
    delta = to_matrix(rng.normal(0, 1, (2, 3)) * 0.05)
    shift = rng.normal(0, 0.01, (2, 3))
    left = hands["left"]
    left.hand_pose = left.hand_pose + noise
    left.global_orient = to_axis_angle(delta @ to_matrix(left.global_orient))
    left.transl = left.transl + shift
    result = join_hands(body, _without_hands(params), left=left, right=hands["right"])
    r = result.residuals["left"]
    assert np.all(r.pca_residual > 0) and np.all(r.pca_residual <= np.linalg.norm(noise, axis=1) + 1e-12)
    assert np.all(r.finger_angle <= np.abs(noise).reshape(2, 15, 3).sum(axis=2).max(axis=1) * 1.5 + 1e-9)
    assert np.all(r.finger_angle > 0)
    assert r.wrist_angle.max() <= 1e-9  # any orientation is reachable through the wrist
    np.testing.assert_allclose(r.wrist_offset, np.linalg.norm(shift, axis=1), rtol=1e-9)
    rig = body.rig
    from smplcore.join.body import local_rotations, world_rotations

    wrist = rig.joint_names.index("left_wrist")
    w0 = world_rotations(rig, local_rotations(rig, params, 2))[:, wrist]
    w1 = world_rotations(rig, local_rotations(rig, result.params, 2))[:, wrist]
    np.testing.assert_allclose(angle_between(w0, w1), np.linalg.norm(to_axis_angle(delta), axis=1), atol=1e-9)
    assert result.residuals["right"].max_angle <= ROT_TOL


def _forearm_radius(body, params, side):
    """Posed over rest mean distance from the elbow-wrist axis of the vertices where the elbow's and the
    wrist's weights meet (wrist weight 0.3-0.7), as the DQS work measures the candy wrapper."""
    rig = body.rig
    elbow, wrist = (rig.joint_names.index(f"{side}_{n}") for n in ("elbow", "wrist"))
    out = body(**params)
    rest, joints = body.rest_pose(betas=params["betas"][0])
    w = rig.weights
    ring = (w[:, wrist] >= 0.3) & (w[:, wrist] <= 0.7) & (w[:, elbow] + w[:, wrist] > 0.95)
    assert ring.sum() >= 5

    def radius(v, a, b):
        axis = (b - a) / np.linalg.norm(b - a)
        d = v - a
        return np.linalg.norm(d - (d @ axis)[:, None] * axis, axis=1)

    posed = radius(out.vertices[0][ring], out.joints[0, elbow], out.joints[0, wrist])
    return float(posed.mean() / radius(rest[ring], joints[elbow], joints[wrist]).mean())


def test_the_forearm_adjustment_shares_the_twist_without_moving_the_hand(body_of, data):
    body = body_of("smplx", False, False)
    rig = body.rig
    rng = np.random.default_rng(6)
    params, _ = _posed_params(body, rng, batch=1)
    params["betas"][:] = 0.0
    params["body_pose"][:, 3 * 17 : 3 * 18] = 0.0  # left elbow straight: the twist is the wrist's alone
    from smplcore.join.body import local_rotations, rest_joints, world_rotations

    elbow, wrist = rig.joint_names.index("left_elbow"), rig.joint_names.index("left_wrist")
    world = world_rotations(rig, local_rotations(rig, params, 1))
    axis = rig.template_joints[wrist] - rig.template_joints[elbow]
    axis /= np.linalg.norm(axis)
    # the hand turned 150 degrees about the forearm
    hand_world = world[:, elbow] @ to_matrix(np.radians(150.0) * axis[None])
    hand = ManoHand(
        global_orient=hand_world, hand_pose=params["left_hand_pose"] + body.rig.hand_means["left_hand_pose"]
    )
    plain = join_hands(body, params, left=hand)
    shared = join_hands(body, params, left=hand, forearm_twist=0.5)
    rp, rs = plain.residuals["left"], shared.residuals["left"]
    np.testing.assert_allclose(rp.forearm_twist_before, np.radians(150.0), atol=1e-9)
    np.testing.assert_allclose(rs.forearm_twist_after, np.radians(75.0), atol=1e-9)
    assert rs.wrist_angle.max() <= 1e-9 and rs.finger_angle.max() <= 1e-9
    # the hand's joints do not move; the vertices only by the pose correctives of the changed elbow/wrist angles
    jp, js = body(**plain.params).joints, body(**shared.params).joints
    hand_joints = [wrist] + [i for i, n in enumerate(rig.joint_names) if n.startswith("left_") and n[-1] in "123"]
    np.testing.assert_allclose(js[:, hand_joints], jp[:, hand_joints], atol=1e-9)
    flat_data = data["smplx"].replace(posedirs=np.zeros_like(data["smplx"].posedirs))
    no_correctives = smplcore.BodyModel(data=flat_data, dtype=np.float64, use_pca=False, flat_hand_mean=False)
    assert _hand_vertex_error(no_correctives, plain.params, shared.params, threshold=1 - 1e-9) <= 1e-9  # hand only
    # and the candy wrapper is smaller: the forearm keeps more of its radius where elbow and wrist weights meet
    before, after = _forearm_radius(body, plain.params, "left"), _forearm_radius(body, shared.params, "left")
    print(f"forearm radius in the blend zone after a 150° hand twist: wrist only {before:.3f}, shared {after:.3f}")
    assert after > before + 0.05
    # the limit holds: the elbow takes at most 30 degrees
    limited = join_hands(body, params, left=hand, forearm_twist=0.5, forearm_twist_limit=np.radians(30.0))
    np.testing.assert_allclose(limited.residuals["left"].forearm_twist_after, np.radians(120.0), atol=1e-9)
    assert rest_joints(rig, None, 1).shape == (1, 55, 3)


def test_left_mano_shapedirs_defect_is_detected_and_fixed(fake_models, manos):
    left, right = manos("left"), manos("right")
    assert left_shapedirs_flipped(left, right)
    fixed = fixed_left_shapedirs(left)
    r = right.rig.shapedirs
    np.testing.assert_allclose(fixed, r * np.array([-1.0, 1.0, 1.0])[None, :, None], atol=1e-12)  # a true mirror
    # with the fix, the same betas put the two wrists at mirrored places
    from smplcore.join.mano import mano_wrist

    betas = np.random.default_rng(7).normal(0, 2, (3, 10))
    wl = mano_wrist(left.rig, betas, np.zeros(3))
    wr = mano_wrist(right.rig, betas, np.zeros(3))
    np.testing.assert_allclose(wl, wr * np.array([-1.0, 1.0, 1.0]), atol=1e-12)
    unfixed = mano_wrist(left.rig, betas, np.zeros(3), fix_left_shapedirs=False)
    assert np.abs(unfixed - wr * np.array([-1.0, 1.0, 1.0])).max() > 1e-5


def test_join_hands_refuses_wrong_inputs(body_of, manos, fake_models):
    body = body_of("smplx", False, False)
    params = {"body_pose": np.zeros((1, 63))}
    hand = {"global_orient": np.zeros(3), "hand_pose": np.zeros(45)}
    with pytest.raises(ValueError, match="left.model: expected a left MANO model"):
        join_hands(body, params, left=ManoHand(np.zeros(3), np.zeros(45), model=manos("right")))
    with pytest.raises(ValueError, match=r"mirrored: the other side's model"):
        join_hands(body, params, left=ManoHand(np.zeros(3), np.zeros(45), model=manos("left"), mirrored=True))
    with pytest.raises(ValueError, match="not both"):
        join_hands(body, params, right=ManoHand(np.zeros(3), np.zeros(45), model=manos("right"), flat_hand_mean=True))
    with pytest.raises(ValueError, match="hand_mean"):
        join_hands(body, params, right=ManoHand(np.zeros(3), np.zeros(45), flat_hand_mean=False))
    with pytest.raises(ValueError, match="absolute finger rotations"):
        join_hands(
            body,
            params,
            right=ManoHand(np.zeros(3), np.tile(np.eye(3), (15, 1, 1)), flat_hand_mean=False, hand_mean=np.ones(45)),
        )
    with pytest.raises(ShapeError, match=r"right.hand_pose: expected \(B, 45\)"):
        join_hands(body, params, right={"global_orient": np.zeros(3), "hand_pose": np.zeros(7)})
    with pytest.raises(ValueError, match="at least one hand"):
        join_hands(body, params)
    with pytest.raises(ValueError, match="forearm_twist"):
        join_hands(body, params, right=hand, forearm_twist=2.0)
    with pytest.raises(ValueError, match="NaN"):
        join_hands(body, params, right={"global_orient": np.full(3, np.nan), "hand_pose": np.zeros(45)})
    smpl = smplcore.BodyModel(fake_models["smpl_neutral_pkl"], dtype=np.float64)
    with pytest.raises(ValueError, match="expected an SMPL-X or SMPL\\+H model"):
        join_hands(smpl, params, right=hand)
    with pytest.raises(ShapeError, match="batch sizes"):
        join_hands(
            body,
            {"body_pose": np.zeros((2, 63))},
            right={"global_orient": np.zeros((3, 3)), "hand_pose": np.zeros((3, 45))},
        )


def test_torch_models_and_tensors_join_like_numpy(fake_models, body_of):
    """A torch model reads the same facts; torch tensors (with grad, as estimators output them) are read as
    NumPy values."""
    torch = pytest.importorskip("torch")
    model = smplcore.create(fake_models["smplx_neutral_npz"], model_type="smplx", use_pca=False, dtype=torch.float64)
    body = body_of("smplx", False, False)
    params, _ = _posed_params(body, np.random.default_rng(8))
    hands = split_hands(body, params)
    a = join_hands(body, _without_hands(params), **hands).params
    tensors = {k: torch.tensor(v, requires_grad=True) for k, v in _without_hands(params).items()}
    right = hands["right"]
    right_t = ManoHand(
        global_orient=torch.tensor(to_matrix(right.global_orient)[:, None], requires_grad=True),
        hand_pose=torch.tensor(right.hand_pose),
    )
    b = join_hands(model, tensors, left=hands["left"], right=right_t).params
    for key in a:
        np.testing.assert_allclose(a[key], b[key], atol=1e-12)


def test_body_rotations_as_matrices_join_like_axis_angle(body_of):
    """Body estimators (HMR2, 4DHumans) give rotation matrices: the same body as matrices joins the same."""
    body = body_of("smplx", False, False)
    params, _ = _posed_params(body, np.random.default_rng(15))
    hands = split_hands(body, params)
    as_matrices = dict(_without_hands(params))
    as_matrices["global_orient"] = to_matrix(params["global_orient"])[:, None]
    as_matrices["body_pose"] = to_matrix(_without_hands(params)["body_pose"].reshape(2, 21, 3))
    a = join_hands(body, _without_hands(params), **hands).params
    b = join_hands(body, as_matrices, **hands).params
    for key in ("global_orient", "body_pose", "left_hand_pose", "right_hand_pose"):
        np.testing.assert_allclose(b[key], a[key], atol=1e-12)


def test_the_forearm_adjustment_keeps_the_hand_in_any_arm_pose(body_of):
    """With a bent, twisted elbow and shaped body, the shared twist still leaves every hand joint in place and
    the hand's orientation exact; the wrist's twist is halved (within the limit)."""
    body = body_of("smplx", False, False)
    rig = body.rig
    params, _ = _posed_params(body, np.random.default_rng(16), batch=3)
    hands = split_hands(body, params)
    plain = join_hands(body, params, **hands)
    shared = join_hands(body, params, **hands, forearm_twist=0.5, forearm_twist_limit=np.pi)
    for side in ("left", "right"):
        r = shared.residuals[side]
        np.testing.assert_allclose(r.forearm_twist_after, r.forearm_twist_before / 2, atol=1e-9)
        assert r.max_angle <= 1e-9
    hand_joints = [i for i, n in enumerate(rig.joint_names) if n.endswith("wrist") or n[-1] in "123"]
    np.testing.assert_allclose(
        body(**shared.params).joints[:, hand_joints], body(**plain.params).joints[:, hand_joints], atol=1e-9
    )


def test_split_hands_relative_to_a_mean_needs_a_body_with_one(body_of):
    body = body_of("smplx", False, True)
    with pytest.raises(ValueError, match="flat_hand_mean=False: the body model has no mean hand pose"):
        split_hands(body, {"body_pose": np.zeros((1, 63))}, flat_hand_mean=False)
    with pytest.raises(ValueError, match=r"hand_models: keys are 'left' and 'right'"):
        split_hands(body, {"body_pose": np.zeros((1, 63))}, hand_models={"both": None})
