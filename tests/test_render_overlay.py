"""render_overlay / side_view: a fit's meshes drawn through its camera over a photo, checked on the PNG read back."""

from __future__ import annotations

import numpy as np
import pytest

import smplcore
from smplcore import fit
from smplcore.render import render_mesh, render_overlay, save_overlay, side_view


@pytest.fixture(scope="module")
def gl() -> None:
    """Skip, with the reason, only when no offscreen OpenGL context can be made."""
    tri = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
    try:
        render_mesh(tri, np.array([[0, 1, 2]]), width=8, height=8)
    except RuntimeError as exc:
        if "could not create an offscreen OpenGL context" in str(exc):
            pytest.skip(f"offscreen OpenGL (EGL/OSMesa) cannot be initialised: {exc}")
        raise


@pytest.fixture(scope="module")
def scene():
    """The open model standing 4.5 m in front of a camera whose principal point is off the image's centre."""
    model = smplcore.BodyModel(model_type="open", dtype=np.float64)
    params = {"global_orient": np.array([[np.pi, 0.0, 0.0]]), "transl": np.array([[0.1, -0.1, 4.5]])}
    camera = fit.Camera(focal=500.0, center=(190.0, 170.0), image_size=(400, 300))
    vertices = np.asarray(model(**params).vertices)[0]
    yy, xx = np.mgrid[0:300, 0:400]
    photo = np.stack([xx * 255 // 400, yy * 255 // 300, np.full_like(xx, 90)], -1).astype(np.uint8)
    return model, vertices, camera, photo


def _read(path):
    from PIL import Image

    with Image.open(path) as img:
        return np.asarray(img.convert("RGB"))


def test_the_mesh_lands_where_the_camera_projects_it(gl, scene, tmp_path):
    model, vertices, camera, photo = scene
    out = save_overlay(tmp_path / "overlay.png", photo, vertices, model.faces, camera, color=(1.0, 0.0, 0.0), alpha=1.0)
    img = _read(out)
    assert img.shape == photo.shape
    drawn = np.any(img != photo, axis=-1)
    rows, cols = np.nonzero(drawn)
    uv = camera.project(vertices)
    assert camera.inside(uv).all()  # the whole body is in the image
    assert abs(cols.min() - uv[:, 0].min()) < 3 and abs(cols.max() - uv[:, 0].max()) < 3
    assert abs(rows.min() - uv[:, 1].min()) < 3 and abs(rows.max() - uv[:, 1].max()) < 3
    assert img[drawn][:, 0].mean() > 150 and img[drawn][:, 2].mean() < 60  # the red body, shaded
    centre = np.round(camera.project(vertices.mean(0, keepdims=True))[0]).astype(int)
    assert drawn[centre[1], centre[0]]
    assert np.array_equal(img[~drawn], photo[~drawn])  # the photo untouched elsewhere


def test_blending_keypoints_and_a_blank_canvas(gl, scene):
    model, vertices, camera, photo = scene
    half = render_overlay(photo, vertices, model.faces, camera, color=(1.0, 0.0, 0.0), alpha=0.5)
    full = render_overlay(photo, vertices, model.faces, camera, color=(1.0, 0.0, 0.0), alpha=1.0)
    drawn = np.any(full != photo, axis=-1)
    mix = half[drawn].astype(float)
    assert np.all(np.abs(mix - 0.5 * (photo[drawn].astype(float) + full[drawn])) <= 1.5)
    dots = render_overlay(None, vertices, model.faces, camera, keypoints=np.array([[20.0, 30.0, 0.9], [40, 30, 0.0]]))
    assert dots.shape == (300, 400, 3)  # the camera's image size
    assert tuple(dots[30, 20]) == (230, 38, 26) and tuple(dots[30, 40]) == (255, 255, 255)  # low confidence: no dot


def test_side_view_shows_depth(gl, scene):
    model, vertices, camera, _ = scene
    front = side_view(vertices, model.faces, camera, angle=0.0, width=200, height=200)
    side = side_view(vertices, model.faces, camera, width=200, height=200)

    def width(img):
        cols = np.nonzero(np.any(img < 250, axis=(0, 2)))[0]
        return cols.max() - cols.min()

    assert width(side) < 0.5 * width(front)  # the T-pose's arm span seen end-on


def test_errors_name_the_argument(scene):
    model, vertices, camera, photo = scene
    with pytest.raises(TypeError, match="camera"):
        render_overlay(photo, vertices, model.faces, (500.0, 190.0))
    with pytest.raises(ValueError, match="image"):
        render_overlay(None, vertices, model.faces, fit.Camera(focal=500.0, center=(190.0, 170.0)))
    with pytest.raises(ValueError, match="alpha"):
        render_overlay(photo, vertices, model.faces, camera, alpha=2.0)
    with pytest.raises(FileNotFoundError, match="image"):
        render_overlay("no_such_photo.jpg", vertices, model.faces, camera)
    with pytest.raises(ValueError, match=".png"):
        save_overlay("overlay.jpg", photo, vertices, model.faces, camera)
