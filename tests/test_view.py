"""smplcore.view without a browser: inputs, posing, the viewer's widgets acting on the server-side scene,
model switch, save buttons, the CLI's missing-extra message."""

from __future__ import annotations

import socket
import time
import warnings

import numpy as np
import pytest

import smplcore
from smplcore.cli import main
from smplcore.export import save_bvh
from smplcore.motion import Motion, save_motion
from smplcore.view import Body, build_model, load_keypoints, load_source
from smplcore.view.sources import Source


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def walk(frames: int = 12, fps: float = 30.0, width: int = 72) -> Motion:
    """A smooth synthetic walk: hips and knees swing, arms down, the body moves along +Z."""
    t = np.arange(frames) / fps
    w = 2 * np.pi * t
    poses = np.zeros((frames, width))
    poses[:, 3 * 1] = 0.5 * np.sin(w)
    poses[:, 3 * 2] = -0.5 * np.sin(w)
    poses[:, 3 * 4] = 0.3 * (1 - np.cos(w))
    poses[:, 3 * 5] = 0.3 * (1 + np.cos(w))
    poses[:, 3 * 16 + 2] = -1.2
    poses[:, 3 * 17 + 2] = 1.2
    trans = np.stack([np.zeros(frames), 0.02 * np.sin(w), 0.8 * t], axis=1)
    model_type = {72: "smpl", 156: "smplh", 165: "smplx"}[width]
    return Motion(poses=poses, trans=trans, betas=np.linspace(-1, 1, 10), fps=fps, model_type=model_type)


@pytest.fixture(scope="module")
def open_model():
    return smplcore.BodyModel(model_type="open")


# --------------------------------------------------------------------------------------------------
# inputs


def test_load_source_tells_model_motion_params_and_bvh_apart(tmp_path, fake_models, open_model):
    motion_path = save_motion(walk(), tmp_path / "walk.npz")
    params_path = tmp_path / "fit.npz"
    np.savez(params_path, betas=np.ones(10), body_pose=np.zeros((3, 69)))
    bvh_path = tmp_path / "walk.bvh"
    save_bvh(bvh_path, open_model, walk())

    assert load_source(fake_models["smplx_neutral_npz"]).model_path == fake_models["smplx_neutral_npz"]
    assert load_source(fake_models["smpl_neutral_pkl"]).model_path is not None
    assert load_source(motion_path).motion.num_frames == 12
    params = load_source(params_path).params
    assert params["body_pose"].shape == (3, 69)
    bvh = load_source(bvh_path).bvh
    assert bvh.names[0] == "pelvis" and bvh.rotations.shape == (12, 24, 3, 3)
    assert bvh.fps == pytest.approx(30.0, rel=1e-6)
    with pytest.raises(FileNotFoundError, match="missing.npz"):
        load_source(tmp_path / "missing.npz")


@pytest.mark.parametrize("scale", [1.0, 100.0])
def test_bvh_export_read_back_reproduces_the_joints(tmp_path, open_model, scale):
    motion = walk()
    motion = Motion(
        poses=motion.poses, trans=motion.trans, betas=np.zeros(10), fps=motion.fps, model_type="smpl"
    )  # a BVH has no betas
    save_bvh(tmp_path / "m.bvh", open_model, motion, scale=scale)
    body = Body(open_model, load_source(tmp_path / "m.bvh"))
    expected = open_model(**motion.model_params("open"))
    for k in (0, 5, 11):
        body.set_frame(k)
        verts, joints = body.evaluate()
        np.testing.assert_allclose(joints, expected.joints[k, :24], atol=2e-4)
        np.testing.assert_allclose(verts, expected.vertices[k], atol=5e-4)


def test_bvh_with_unknown_joints_is_refused_with_the_file_name(tmp_path, open_model):
    path = tmp_path / "other.bvh"
    path.write_text(
        "HIERARCHY\nROOT Hips\n{\n\tOFFSET 0 0 0\n\tCHANNELS 6 Xposition Yposition Zposition Zrotation Yrotation "
        "Xrotation\n\tEnd Site\n\t{\n\t\tOFFSET 0 1 0\n\t}\n}\nMOTION\nFrames: 1\nFrame Time: 0.033333\n0 0 0 0 0 0\n"
    )
    with pytest.raises(ValueError, match="other.bvh.*none of its 1 joints"):
        Body(open_model, load_source(path))


def test_load_keypoints_shapes_and_errors(tmp_path):
    np.save(tmp_path / "k.npy", np.zeros((17, 3)))
    assert load_keypoints(tmp_path / "k.npy").shape == (1, 17, 3)
    np.savez(tmp_path / "k.npz", keypoints=np.ones((5, 17, 4)))
    assert load_keypoints(tmp_path / "k.npz").shape == (5, 17, 3)
    np.save(tmp_path / "bad.npy", np.zeros((17, 2)))
    with pytest.raises(ValueError, match=r"bad.npy.*\(K, 3\)"):
        load_keypoints(tmp_path / "bad.npy")


# --------------------------------------------------------------------------------------------------
# posing


def test_body_evaluates_like_the_model_and_frames_batch_like_single_ones(open_model):
    body = Body(open_model, Source(label="walk", motion=walk()))
    params = walk().model_params("open")
    expected = open_model(**params)
    body.set_frame(7)
    verts, joints = body.evaluate()
    np.testing.assert_allclose(verts, expected.vertices[7], atol=1e-5)
    batch, _ = body.evaluate_frames(3, 9)
    np.testing.assert_allclose(batch[4], expected.vertices[7], atol=1e-5)
    assert batch.shape == (6, *verts.shape)


def test_the_open_model_is_built_in_the_gender_asked_for():
    for gender in ("male", "female"):
        expected = smplcore.BodyModel(model_type="open", gender=gender).setup.data.v_template
        np.testing.assert_array_equal(build_model(gender=gender).setup.data.v_template, expected)


def test_body_on_smplx_takes_a_smplh_motion_by_joint_name(fake_models):
    model = build_model(fake_models["smplx_neutral_npz"], "smplx", flat_hand_mean=True)
    body = Body(model, Source(label="walk", motion=walk(width=156)))
    assert body.full_pose.shape == (55, 3)
    body.set_frame(3)
    np.testing.assert_allclose(body.full_pose[1], walk(width=156).poses[3, 3:6], atol=1e-6)
    verts, joints = body.evaluate()
    assert verts.shape == (10475, 3) and joints.shape == (55, 3)


# --------------------------------------------------------------------------------------------------
# the viewer, server side


viser = pytest.importorskip("viser", reason="the viewer needs viser: pip install 'smplcore[view]'")


@pytest.fixture
def viewer(tmp_path):
    from smplcore.view import show

    v = show(port=free_port(), out_dir=tmp_path)
    yield v
    v.close()


def test_beta_slider_reposes_the_scene_mesh(viewer, open_model):
    mesh = viewer._nodes[0]["mesh"]
    before = np.array(mesh.vertices)
    np.testing.assert_allclose(before, open_model().vertices[0], atol=1e-5)
    viewer.controls.betas[0].value = 2.0
    after = np.array(mesh.vertices)
    np.testing.assert_allclose(after, open_model(betas=np.array([[2.0] + [0.0] * 9])).vertices[0], atol=1e-5)
    assert np.abs(after - before).max() > 0.01
    assert len(viewer.timings) >= 1


def test_age_slider_rebuilds_the_open_model_at_that_age_keeping_shape_and_pose(viewer):
    from smplcore import BodyModel

    c = viewer.controls
    assert c.age is not None and c.age.value == 25.0  # the open model: an age slider, the adult to start
    c.betas[0].value = 1.0
    c.joint.value = "left_shoulder"
    c.rotation[2].value = -60.0
    c.age.value = 6.0
    kid = BodyModel(model_type="open", gender="neutral", age=6.0, num_betas=10)
    assert viewer.ages[0] == 6.0 and viewer.bodies[0].betas[0] == 1.0
    pose = np.zeros((1, 69))
    pose[0, 3 * (kid.skeleton_joint_names.index("left_shoulder") - 1) + 2] = -np.pi / 3
    expected = kid(betas=np.array([[1.0] + [0.0] * 9]), body_pose=pose).vertices[0]
    mesh = np.array(viewer._nodes[0]["mesh"].vertices)
    np.testing.assert_allclose(mesh, expected, atol=1e-5)
    assert np.ptp(mesh[:, 1]) < 1.3  # a six-year-old, not the adult
    c.age.value = float("nan")  # a bad value from a client leaves the body as it was
    assert viewer.ages[0] == 6.0 and c.age.value == 6.0
    c.gender.value = "female"  # another gender keeps the age
    assert viewer.ages[0] == 6.0 and c.age.value == 6.0
    np.testing.assert_allclose(
        np.array(viewer._nodes[0]["mesh"].vertices),
        BodyModel(model_type="open", gender="female", age=6.0)(
            betas=np.array([[1.0] + [0.0] * 9]), body_pose=pose
        ).vertices[0],
        atol=1e-5,
    )


def test_joint_rotation_sliders_rotate_the_picked_joint(viewer, open_model):
    c = viewer.controls
    c.joint.value = "left_shoulder"
    c.rotation[2].value = -60.0
    j = open_model.skeleton_joint_names.index("left_shoulder")
    np.testing.assert_allclose(viewer.bodies[0].full_pose[j], [0, 0, -np.pi / 3], atol=1e-6)
    pose = np.zeros((1, 69))
    pose[0, 3 * (j - 1) + 2] = -np.pi / 3
    np.testing.assert_allclose(viewer._nodes[0]["mesh"].vertices, open_model(body_pose=pose).vertices[0], atol=1e-5)
    c.joint.value = "pelvis"  # the sliders show the picked joint's rotation
    assert [s.value for s in c.rotation] == [0.0, 0.0, 0.0]
    c.joint.value = "left_shoulder"
    assert c.rotation[2].value == -60.0


def test_timeline_and_bodies_side_by_side(tmp_path):
    from smplcore.view import Viewer

    motion_path = save_motion(walk(), tmp_path / "walk.npz")
    with Viewer([motion_path, Source(label="rest")], port=free_port()) as v:
        assert v.num_frames == 12 and len(v.bodies) == 2
        c = v.controls
        c.frame.value = 6
        expected = v.bodies[0].model(**walk().model_params("open"))  # betas from the motion
        np.testing.assert_allclose(v._nodes[0]["mesh"].vertices, expected.vertices[6], atol=1e-5)
        c.advance(7)  # wraps around: (6 + 7) % 12
        assert c.frame.value == 1 and v.bodies[0].frame == 1
        x0 = v._nodes[0]["frame"].position[0]
        x1 = v._nodes[1]["frame"].position[0]
        assert x1 - x0 > 1.0  # side by side, not overlapping
        c.play.value = True
        c.speed_slider.value = 4.0
        deadline = time.time() + 5
        while c.frame.value == 1 and time.time() < deadline:
            time.sleep(0.05)
        assert c.frame.value != 1  # playing moves the timeline


def test_skeleton_and_names_follow_the_pose(viewer):
    c = viewer.controls
    c.skeleton.value = True
    c.names.value = True
    nodes = viewer._nodes[0]
    assert nodes["skeleton"].visible and nodes["names"][0].visible
    c.joint.value = "left_elbow"
    c.rotation[1].value = 90.0
    _, joints = viewer.bodies[0].evaluate()
    np.testing.assert_allclose(nodes["joints"].points, joints, atol=1e-5)
    wrist = viewer.bodies[0].joint_names.index("left_wrist")
    np.testing.assert_allclose(nodes["names"][wrist].position, joints[wrist], atol=1e-5)
    assert len(nodes["names"]) == 24 and nodes["names"][wrist].text == "left_wrist"


def test_model_switch_to_smplx_and_a_missing_model(tmp_path, fake_models):
    from smplcore.view import Viewer

    with Viewer(model_path=fake_models["root"], model_type="smpl", port=free_port()) as v:
        c = v.controls
        c.betas[1].value = 1.5
        c.model.value = "smplx"
        assert v.bodies[0].model.model_type == "smplx"
        assert np.array(v._nodes[0]["mesh"].vertices).shape == (10475, 3)
        assert v.bodies[0].betas[1] == pytest.approx(1.5)  # shape carried over
        assert len(c.expression) == 10
        c.expression[0].value = 2.0
        assert v.bodies[0].expression[0] == 2.0
        c.gender.value = "male"
        assert v.bodies[0].model is not None and "smplx (male)" in c.status.content
        model_before = v.bodies[0].model
        c.gender.value = "female"  # the fake folder has no SMPLX_FEMALE: shown, the body keeps its model
        assert "could not load smplx / female" in c.status.content
        assert v.bodies[0].model is model_before


def test_save_buttons_write_mesh_and_glb(viewer, tmp_path):
    import trimesh

    viewer.controls.betas[0].value = 1.0
    mesh_path = viewer.save_mesh()
    loaded = trimesh.load(mesh_path, process=False)
    np.testing.assert_allclose(loaded.vertices, viewer._nodes[0]["mesh"].vertices, atol=1e-5)
    glb = viewer.save_glb()
    assert glb.read_bytes()[:4] == b"glTF"
    viewer.controls.save_mesh.value = True  # what a click does on the server
    assert "saved" in viewer.controls.status.content


def test_show_takes_a_torch_model_and_params(fake_models):
    pytest.importorskip("torch")
    from smplcore.view import show

    model = smplcore.create(fake_models["smplx_neutral_npz"], model_type="smplx")
    pose = np.zeros((1, 63))
    pose[0, 50] = 1.0
    v = show(model, {"body_pose": pose, "betas": np.ones((1, 10))}, port=free_port())
    try:
        verts = np.array(v._nodes[0]["mesh"].vertices)
        expected = smplcore.BodyModel(fake_models["smplx_neutral_npz"], model_type="smplx")(
            body_pose=pose, betas=np.ones((1, 10))
        )
        np.testing.assert_allclose(verts, expected.vertices[0], atol=1e-4)
    finally:
        v.close()


# --------------------------------------------------------------------------------------------------
# CLI


def test_missing_extra_is_one_line_and_exit_2(monkeypatch, capsys, tmp_path):
    import importlib

    import smplcore.view._deps as deps

    real = importlib.import_module

    def fake_import(name, *args):
        if name in ("viser", "imageio_ffmpeg"):
            raise ImportError(f"No module named '{name}'")
        return real(name, *args)

    monkeypatch.setattr(deps.importlib, "import_module", fake_import)
    assert main(["view", "--port", str(free_port())]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and 'pip install "smplcore[view]"' in err and "viser" in err
    save_motion(walk(), tmp_path / "walk.npz")
    assert main(["render", str(tmp_path / "walk.npz"), "-o", str(tmp_path / "w.mp4")]) == 2
    err = capsys.readouterr().err.strip()
    assert 'pip install "smplcore[view]"' in err and "imageio_ffmpeg" in err
    monkeypatch.undo()
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert main(["view", str(tmp_path / "nope.npz")]) == 2
    assert "nope.npz: no such file" in capsys.readouterr().err


def test_target_keypoints_follow_the_timeline(tmp_path):
    from smplcore.view import Viewer

    targets = np.random.default_rng(0).normal(size=(12, 5, 3))
    np.save(tmp_path / "target.npy", targets)
    with Viewer([save_motion(walk(), tmp_path / "walk.npz")], keypoints=tmp_path / "target.npy", port=free_port()) as v:
        np.testing.assert_allclose(v._nodes[0]["keypoints"].points, targets[0], atol=1e-6)
        v.controls.frame.value = 9
        np.testing.assert_allclose(v._nodes[0]["keypoints"].points, targets[9], atol=1e-6)


def test_a_refused_browser_value_is_put_back_later_and_never_over_a_newer_move(viewer):
    """viser sets a slider from each browser message in its own thread and runs the callbacks in a pool: the
    put-back of a refused (NaN) value must not overwrite a valid move that arrived meanwhile."""
    from types import SimpleNamespace

    from smplcore.view.controls import PUT_BACK_DELAY

    c, browser = viewer.controls, SimpleNamespace(client=object())
    slider = c.betas[2]
    with c._silent():  # as viser's message thread sets it
        slider.value = float("nan")
    assert c._checked(slider, 0.5, -3.0, 3.0, browser) is None
    with c._silent():
        slider.value = 2.0  # the next message, arriving before the put-back
    time.sleep(4 * PUT_BACK_DELAY)
    assert slider.value == 2.0
    with c._silent():
        slider.value = float("nan")
    assert c._checked(slider, 0.5, -3.0, 3.0, browser) is None
    deadline = time.monotonic() + 30
    while slider.value != 0.5 and time.monotonic() < deadline:
        time.sleep(0.02)
    assert slider.value == 0.5  # nothing newer came: the slider shows the body's value again
