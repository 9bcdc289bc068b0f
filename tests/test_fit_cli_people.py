"""``smplcore fit`` on several people: a COCO file's people each with their own shape, OpenPose people tracked
over the frames (``--person N`` / ``all``), and the photo overlay (``--overlay``, ``--image``)."""

from __future__ import annotations

import json

import numpy as np
import pytest

import smplcore
from fakes_fit2d import CAMERA, natural_poses, scene, write_coco
from smplcore.cli import main
from smplcore.errors import ModelFileError
from smplcore.fit.tracks import track_people
from smplcore.motion import load_motion


@pytest.fixture(scope="module")
def open_model():
    return smplcore.BodyModel(model_type="open", dtype=np.float64)


def _people(model, betas0: list[float], seed: int = 0) -> dict[str, np.ndarray]:
    """People side by side, 3.5 m away, whose first shape coefficient (the open model's height) is ``betas0``."""
    rng = np.random.default_rng(seed)
    params = natural_poses(model, len(betas0), rng, spread=0.05)
    params["global_orient"] = np.tile([np.pi, 0.0, 0.0], (len(betas0), 1))
    params["betas"] = np.zeros((len(betas0), 10))
    params["betas"][:, 0] = betas0
    params["transl"] = np.c_[np.linspace(-1.2, 1.2, len(betas0)), np.full(len(betas0), 0.1), np.full(len(betas0), 3.5)]
    return params


def test_a_coco_file_of_three_people_gets_three_shapes(tmp_path, open_model):
    params = _people(open_model, [-2.0, 0.0, 2.0])
    keypoints, _, _ = scene(open_model, params, np.random.default_rng(1), noise=0.5)
    path = write_coco(tmp_path / "three.json", keypoints, 1000, 1000)
    out = tmp_path / "three.npz"
    assert main(["fit", str(path), "-o", str(out), "--focal", "1000", "--center", "500,500"]) == 0
    with np.load(out) as data:
        betas, person = data["betas"], data["person"]
    assert betas.shape == (3, 10)  # before: one shared (10,) for three different people
    assert len(np.unique(betas.round(6), axis=0)) == 3
    # each row is that person's own fit (2D alone cannot tell a tall person far away from a short one near:
    # the shapes are the fits', not the truth's)
    for row, p in enumerate(person):
        alone = smplcore.fit.fit_keypoints(open_model, keypoints[p : p + 1], camera=CAMERA)
        np.testing.assert_allclose(betas[row], alone.params["betas"][0], atol=0.05)
    # a motion is one person: the readers of export / process refuse the file, saying why
    with pytest.raises(ModelFileError, match="different people"):
        load_motion(out)


def _openpose_people(folder, model, frames: int, seed: int = 0) -> tuple[dict, np.ndarray]:
    """Two people walking apart (left one short, right one tall) over ``frames`` frames, written in a random
    order per frame; in frame 1 the tall one is missing; a third person appears in the last two frames."""
    params = _people(model, [-2.0, 2.0, 0.0], seed)
    rng = np.random.default_rng(seed)
    folder.mkdir(parents=True)
    orders = []
    for t in range(frames):
        moved = {k: v.copy() for k, v in params.items()}
        moved["transl"][:2, 0] += np.array([-0.05, 0.05]) * t
        moved["transl"][2, 2] = 6.0  # the third, farther away
        keypoints, _, _ = scene(model, moved, rng, noise=0.5, convention="openpose25")
        present = [0, 1] + ([2] if t >= frames - 2 else [])
        if t == 1:
            present.remove(1)
        order = rng.permutation(present)
        orders.append(order)
        doc = {"version": 1.3, "people": [{"pose_keypoints_2d": keypoints[p].reshape(-1).tolist()} for p in order]}
        (folder / f"frame_{t:04d}_keypoints.json").write_text(json.dumps(doc))
    return params, orders


def test_track_people_follows_people_whose_order_changes():
    rng = np.random.default_rng(0)
    box = rng.uniform(0, 100, (2, 17, 2))  # two people's keypoints
    box[1] += 400.0
    points = np.zeros((6, 3, 17, 3))
    orders = [[0, 1], [1, 0], [0], [1, 0, 2], [0, 1], [1, 0]]
    for t, order in enumerate(orders):
        for slot, p in enumerate(order):
            if p == 2:
                points[t, slot, :, :2] = rng.uniform(800, 900, (17, 2))  # someone new
            else:
                points[t, slot, :, :2] = box[p] + 3.0 * t
            points[t, slot, :, 2] = 0.9
    tracks = track_people(points)
    assert tracks.shape == (6, 3, 17, 3)
    first = tracks[:, 0, 0, :2]  # track 0 is the person seen in the most frames: person 0 (6 frames)
    assert np.allclose(first - 3.0 * np.arange(6)[:, None], box[0, 0])
    assert np.array_equal(tracks[:, 1, 0, 2] > 0, [True, True, False, True, True, True])  # person 1, gone in frame 2
    assert np.array_equal(tracks[:, 2, 0, 2] > 0, [False, False, False, True, False, False])


def test_openpose_people_are_tracked_each_with_its_shape(tmp_path, open_model):
    params, orders = _openpose_people(tmp_path / "op", open_model, 5)
    out = tmp_path / "one.npz"
    camera = ["--focal", "1000", "--center", "500,500"]
    assert main(["fit", str(tmp_path / "op"), "-o", str(out), *camera]) == 0
    with np.load(out) as data:
        trans, betas = data["trans"], data["betas"]
    assert betas.shape == (10,)  # one person
    # track 0 (seen in every frame): the person on the left, all along (before: whoever was listed first)
    assert np.all(np.abs(np.diff(trans[:, 0]) + 0.05) < 0.1)
    every = tmp_path / "all.npz"
    assert main(["fit", str(tmp_path / "op"), "-o", str(every), *camera, "--person", "all"]) == 0
    with np.load(every) as data:
        track, frame, betas = data["track"], data["frame"], data["betas"]
    assert np.bincount(track).tolist() == [5, 4, 2] and betas.shape == (11, 10)
    assert frame[track == 1].tolist() == [0, 2, 3, 4]
    for n in range(3):
        assert np.ptp(betas[track == n], axis=0).max() < 1e-9  # one shape per track
    assert len(np.unique(betas.round(6), axis=0)) == 3  # and three of them
    with np.load(every) as data:
        x = data["trans"][:, 0]
    assert x[track == 0].max() < x[track == 1].min()  # track 0 the left person, track 1 the right one
    assert main(["fit", str(tmp_path / "op"), "-o", str(tmp_path / "x.npz"), *camera, "--person", "3"]) == 1


@pytest.fixture(scope="module")
def gl() -> None:
    """Skip, with the reason, only when no offscreen OpenGL context can be made."""
    from smplcore.render import render_mesh

    try:
        render_mesh(np.eye(3), np.array([[0, 1, 2]]), width=8, height=8)
    except RuntimeError as exc:
        if "could not create an offscreen OpenGL context" in str(exc):
            pytest.skip(f"offscreen OpenGL (EGL/OSMesa) cannot be initialised: {exc}")
        raise


def test_overlay_draws_the_fit_over_the_photo(gl, tmp_path, open_model):
    from PIL import Image

    params = _people(open_model, [0.0, 1.0])
    keypoints, exact, _ = scene(open_model, params, np.random.default_rng(2), noise=0.5)
    path = write_coco(tmp_path / "two.json", keypoints, 1000, 1000)
    photo = np.full((1000, 1000, 3), 40, np.uint8)
    Image.fromarray(photo).save(tmp_path / "photo.png")
    png = tmp_path / "overlay.png"
    image = ["--image", str(tmp_path / "photo.png")]
    assert main(["fit", str(path), "-o", str(tmp_path / "two.npz"), "--overlay", str(png), *image]) == 0
    with Image.open(png) as img:
        drawn = np.asarray(img.convert("RGB"))
    assert drawn.shape == photo.shape
    changed = np.any(drawn != photo, axis=-1)
    for person in exact:  # each person's torso keypoints fall on the drawn bodies
        for k in (5, 6, 11, 12):
            x, y = np.round(person[k]).astype(int)
            assert changed[y, x]
    assert not changed[5:60, 5:60].any()  # the corner, away from the people, untouched
    assert main(["fit", str(path), "-o", str(tmp_path / "t.npz"), *image]) == 2
    assert main(["fit", str(path), "-o", str(tmp_path / "t.npz"), "--overlay", str(tmp_path / "o.jpg")]) == 2


def test_camera_of_the_cli_knows_the_image_size(tmp_path, open_model):
    # a COCO image's size: points outside it (a detector's guesses) do not pull
    params = _people(open_model, [0.0])
    keypoints, exact, _ = scene(open_model, params, np.random.default_rng(3), noise=0.5)
    keypoints[0, 15:, :2] = [[400.0, 1010.0], [600.0, 1020.0]]  # ankles "seen" below a 1000 px tall image
    path = write_coco(tmp_path / "cut.json", keypoints, 1000, 1000)
    out = tmp_path / "cut.npz"
    assert main(["fit", str(path), "-o", str(out), "--focal", "1000", "--center", "500,500"]) == 0
    with np.load(out) as data:
        assert data["fit_error"][0] < 2.0  # the other 15 points fitted; the two wild ones left out
