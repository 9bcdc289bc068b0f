"""smplcore.view.render_video / ``smplcore render``: MP4 and GIF decoded back (frame count, size, frames that
differ), frame-rate change, fixed vs follow camera, target keypoints, batches, argument errors."""

from __future__ import annotations

import numpy as np
import pytest

from smplcore.cli import main
from smplcore.motion import Motion, save_motion

imageio_ffmpeg = pytest.importorskip(
    "imageio_ffmpeg", reason="video needs imageio-ffmpeg: pip install 'smplcore[view]'"
)

from smplcore.view import render_video  # noqa: E402

W, H = 64, 48


@pytest.fixture(scope="module")
def gl() -> None:
    """Skip, with the reason, only when no offscreen OpenGL context can be made."""
    from smplcore.render import render_mesh

    tri = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
    try:
        render_mesh(tri, np.array([[0, 1, 2]]), width=8, height=8)
    except RuntimeError as exc:
        if "could not create an offscreen OpenGL context" in str(exc):
            pytest.skip(f"offscreen OpenGL (EGL/OSMesa) cannot be initialised: {exc}")
        raise


def walk(frames: int = 8, fps: float = 30.0) -> Motion:
    """Legs swinging, walking 2 m/s towards the camera (+Z)."""
    t = np.arange(frames) / fps
    w = 2 * np.pi * 2 * t
    poses = np.zeros((frames, 72))
    poses[:, 3] = 0.6 * np.sin(w)
    poses[:, 6] = -0.6 * np.sin(w)
    poses[:, 3 * 16 + 2] = -1.2
    poses[:, 3 * 17 + 2] = 1.2
    trans = np.stack([np.zeros(frames), np.zeros(frames), 2.0 * t], axis=1)
    return Motion(poses=poses, trans=trans, betas=np.zeros(10), fps=fps, model_type="smpl")


def decode(path) -> tuple[tuple[int, int], np.ndarray]:
    reader = imageio_ffmpeg.read_frames(str(path))
    meta = next(reader)
    w, h = meta["size"]
    frames = np.stack([np.frombuffer(f, np.uint8).reshape(h, w, 3) for f in reader])
    return (w, h), frames


def foreground(frame: np.ndarray) -> np.ndarray:
    return np.any(np.abs(frame.astype(int) - 255) > 40, axis=2)


def test_mp4_decodes_to_the_frames_and_size_with_a_moving_body(gl, tmp_path):
    report = render_video(walk(), tmp_path / "walk.mp4", width=W, height=H, camera="fixed")
    assert report.frames == 8 and report.render_fps > 0
    size, frames = decode(tmp_path / "walk.mp4")
    assert size == (W, H) and frames.shape == (8, H, W, 3)
    for f in frames:
        assert 0.02 < foreground(f).mean() < 0.8  # a body, not an empty or a full frame
    assert np.abs(frames[0].astype(int) - frames[4].astype(int)).mean() > 1.0  # the frames differ


def test_fixed_camera_sees_the_body_come_closer_and_follow_keeps_its_size(gl, tmp_path):
    heights = {}
    for camera in ("fixed", "follow"):
        render_video(walk(), tmp_path / f"{camera}.mp4", width=W, height=H, camera=camera, view="front")
        _, frames = decode(tmp_path / f"{camera}.mp4")
        rows = [np.flatnonzero(foreground(f).any(axis=1)) for f in frames]
        heights[camera] = np.array([r.max() - r.min() for r in rows])
    assert heights["fixed"][-1] > heights["fixed"][0] * 1.05  # walking 14 cm towards a fixed camera
    assert abs(int(heights["follow"][-1]) - int(heights["follow"][0])) <= 2  # the camera keeps its distance


def test_gif_and_a_lower_frame_rate(gl, tmp_path):
    report = render_video(walk(12), tmp_path / "walk.gif", width=W, height=H, fps=10)
    assert report.frames == 4 and report.fps == 10
    size, frames = decode(tmp_path / "walk.gif")
    assert size == (W, H) and len(frames) == 4
    assert (tmp_path / "walk.gif").read_bytes()[:6] == b"GIF89a"


def test_target_keypoints_are_drawn_over_the_body(gl, tmp_path, monkeypatch):
    import smplcore.view.video as video

    calls = []
    original = video.Body.evaluate_frames

    def counting(self, start, stop):
        calls.append(stop - start)
        return original(self, start, stop)

    monkeypatch.setattr(video.Body, "evaluate_frames", counting)
    motion = walk(5)
    plain = tmp_path / "plain.mp4"
    render_video(motion, plain, width=2 * W, height=2 * H, camera="fixed", batch=2)
    assert max(calls) <= 2  # frames are posed in batches, never the whole motion at once
    keypoints = np.tile(np.array([[0.5, 0.2, 0.1], [-0.5, 0.2, 0.1]]), (5, 1, 1))
    np.save(tmp_path / "target.npy", keypoints)
    assert main(["render", str(_saved(motion, tmp_path)), "-o", str(tmp_path / "fit.mp4"), "--size", f"{2 * W}x{2 * H}",
                 "--camera", "fixed", "--fit-over", str(tmp_path / "target.npy"), "--no-progress"]) == 0  # fmt: skip
    _, a = decode(plain)
    _, b = decode(tmp_path / "fit.mp4")
    green = (b[..., 1].astype(int) - b[..., 0] > 40) & (b[..., 1].astype(int) - b[..., 2] > 20)
    assert green[0].sum() > 4 and not ((a[..., 1].astype(int) - a[..., 0] > 40) & (a[..., 1] > 100)).any()


def _saved(motion: Motion, tmp_path):
    return save_motion(motion, tmp_path / "motion.npz")


def test_argument_errors_name_the_argument(tmp_path, capsys):
    with pytest.raises(ValueError, match="even width and height"):
        render_video(walk(), tmp_path / "x.mp4", width=65, height=48)
    with pytest.raises(ValueError, match=r"output: expected a file ending in \.mp4 or \.gif"):
        render_video(walk(), tmp_path / "x.avi")
    with pytest.raises(ValueError, match="camera: expected one of follow, fixed"):
        render_video(walk(), tmp_path / "x.mp4", camera="orbit")
    assert main(["render", str(_saved(walk(), tmp_path)), "-o", str(tmp_path / "x.mp4"), "--size", "63x48"]) == 2
    assert "even width and height" in capsys.readouterr().err
