"""A motion to a video (MP4 / GIF): frames posed in batches, drawn with the offscreen renderer
(:func:`smplcore.render.render_mesh`) and streamed to ffmpeg (``imageio-ffmpeg``), so memory stays flat in
the length of the motion.

Cameras:

* ``fixed``: one camera for the whole motion, framing the box the body moves in.
* ``follow``: the camera moves with the body (its box centre, smoothed over half a second) at a constant
  distance, framing the largest extent the body reaches.

:func:`render_mesh` frames every image on the bounding box of the vertices it is given, so the camera box
is handed to it as eight extra vertices that no face uses: they move the framing, not the picture.
"""

from __future__ import annotations

import contextlib
import errno
import gc
import os
import shutil
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from smplcore.view._deps import require
from smplcore.view.bodies import Body, build_model
from smplcore.view.sources import Source, load_keypoints, load_source

CAMERA_MODES = ("follow", "fixed")
SUFFIXES = (".mp4", ".gif")
_SMOOTH_SECONDS = 0.5
_BODY_COLOR = (0.87, 0.63, 0.5)
_KEYPOINT_COLOR = (0.1, 0.65, 0.25)
# Per-frame palettes: a GIF is encoded frame by frame, nothing is buffered for a global palette.
_GIF_FILTER = "split[a][b];[a]palettegen=stats_mode=single[p];[b][p]paletteuse=new=1"


class VideoWriteError(OSError):
    """The video could not be written whole (a full disk, a read-only folder, ffmpeg failing); nothing is left
    at the output path. The message names the file, the frames expected and the frames that decode."""


@dataclass(frozen=True)
class VideoReport:
    """What :func:`render_video` wrote: ``path``, ``frames``, ``fps``, ``width``, ``height`` and the
    wall-clock ``seconds`` it took (``render_fps`` = frames / seconds)."""

    path: Path
    frames: int
    fps: float
    width: int
    height: int
    seconds: float

    @property
    def render_fps(self) -> float:
        return self.frames / self.seconds if self.seconds > 0 else float("inf")

    def summary(self) -> str:
        return (
            f"wrote {self.path} ({self.frames} frames, {self.width}x{self.height}, {self.fps:g} fps) "
            f"in {self.seconds:.1f} s ({self.render_fps:.1f} frames/s)"
        )


def _box_corners(lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """(8, 3) corners of the box [lo, hi]."""
    idx = np.array([[i >> 2 & 1, i >> 1 & 1, i & 1] for i in range(8)])
    return np.where(idx, hi, lo)


def _smooth(values: np.ndarray, window: int) -> np.ndarray:
    """(T, 3) moving average over ``window`` frames (edges averaged over what exists)."""
    if window <= 1 or len(values) < 2:
        return values
    kernel = np.ones(window)
    pad = window // 2
    padded = np.pad(values, ((pad, window - 1 - pad), (0, 0)), mode="edge")
    out = np.stack([np.convolve(padded[:, k], kernel, mode="valid") for k in range(values.shape[1])], axis=1)
    return out / window


def _check_output(path: Path, width: int, height: int) -> str:
    suffix = path.suffix.lower()
    if suffix not in SUFFIXES:
        raise ValueError(f"output: expected a file ending in {' or '.join(SUFFIXES)}, got {str(path)!r}")
    for name, value in (("width", width), ("height", height)):
        if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or not 16 <= value <= 4096:
            raise ValueError(f"{name}: expected 16 to 4096 pixels, got {value!r}")
    if suffix == ".mp4" and (width % 2 or height % 2):
        raise ValueError(f"size: MP4 (H.264, yuv420p) needs an even width and height, got {width}x{height}")
    return suffix


def render_video(
    source: Any,
    output: str | Path,
    *,
    model: Any = None,
    model_path: str | Path | None = None,
    model_type: str | None = None,
    gender: str | None = None,
    fps: float | None = None,
    width: int = 640,
    height: int = 480,
    camera: str = "follow",
    view: str = "front",
    keypoints: Any = None,
    batch: int = 32,
    progress: Callable[[int], Any] | None = None,
    on_start: Callable[[int], Any] | None = None,
) -> VideoReport:
    """Render a motion to ``output`` (``.mp4``: H.264; ``.gif``).

    Parameters
    ----------
    source : a motion (:class:`~smplcore.motion.Motion`, AMASS ``.npz``, ``.bvh``, a parameter set with T
        frames) or a :class:`~smplcore.view.sources.Source`.
    output : the file to write (parent folders are created).
    model : a :class:`smplcore.BodyModel` to pose; else built from ``model_path`` / ``model_type`` /
        ``gender`` (default: the open model).
    fps : frame rate of the video (default: the motion's); other rates take the nearest motion frame.
    width, height : pixels (even for MP4).
    camera : ``"follow"`` or ``"fixed"`` (see the module docs).
    view : the side the camera looks from: ``"front"``, ``"three_quarter"`` or ``"side"``.
    keypoints : target keypoints, (K, 3) or (T, K, 3) array or file, drawn as spheres over the body (which is
        then half transparent), e.g. the keypoints a fit was made to.
    batch : frames posed per model call; memory is O(batch), not O(T).
    progress : called with the number of frames written, e.g. ``tqdm(total=T).update``.
    on_start : called once with the number of frames the video will have, before rendering starts.

    Raises
    ------
    ValueError
        a bad argument (named in the message).
    MissingDependencyError
        imageio-ffmpeg is not installed.
    RuntimeError
        no offscreen OpenGL context (the message says how to fix it).
    VideoWriteError
        the video could not be written whole: what ffmpeg wrote is decoded back and must hold every frame
        (a full disk left GIFs short and MP4s undecodable); nothing is left at ``output`` then.

    The video is written under a temporary name beside ``output`` and renamed into place once its frames
    decode back.
    """
    from smplcore.motion import Motion
    from smplcore.render import CAMERAS, render_mesh

    ffmpeg = require("imageio_ffmpeg", "writing videos")
    _check_installed("pyrender", "writing videos")  # before the writer opens (not imported: OpenGL comes later)
    out = Path(output)
    suffix = _check_output(out, width, height)
    if camera not in CAMERA_MODES:
        raise ValueError(f"camera: expected one of {', '.join(CAMERA_MODES)}, got {camera!r}")
    if view not in CAMERAS:
        raise ValueError(f"view: expected one of {', '.join(CAMERAS)}, got {view!r}")
    if not isinstance(batch, int) or batch < 1:
        raise ValueError(f"batch: expected a positive number of frames, got {batch!r}")
    if isinstance(source, (str, Path)):
        source = load_source(source)
    elif isinstance(source, Motion):
        source = Source(label=Path(source.source).name, motion=source)
    elif not isinstance(source, Source):
        source = Source(label="params", params={k: np.asarray(v) for k, v in dict(source).items()})
    if source.model_path is not None:
        raise ValueError(f"{source.label}: is a body-model file, not a motion; pass it as model_path")
    if model is None:
        g = gender or (source.motion.gender if source.motion is not None else "neutral")
        betas = 10 if source.motion is None else max(10, int(np.asarray(source.motion.betas).size))
        motion_like = source.motion is not None or source.bvh is not None
        model = build_model(model_path, model_type, g, num_betas=betas, flat_hand_mean=motion_like)
    body = Body(model, source)
    src_frames = body.num_frames
    src_fps = body.track.fps if body.track is not None else 30.0
    out_fps = float(fps) if fps is not None else src_fps
    if not (np.isfinite(out_fps) and out_fps > 0):
        raise ValueError(f"fps: expected a positive frame rate, got {fps!r}")
    count = max(1, int(np.floor((src_frames - 1) * out_fps / src_fps + 1e-9)) + 1)
    frame_of = np.minimum(np.round(np.arange(count) * src_fps / out_fps).astype(int), src_frames - 1)
    targets = None
    if keypoints is not None:
        targets = load_keypoints(keypoints) if isinstance(keypoints, (str, Path)) else np.asarray(keypoints, float)
        targets = targets[None] if targets.ndim == 2 else targets
        if targets.ndim != 3 or targets.shape[-1] != 3:
            raise ValueError(f"keypoints: expected shape (K, 3) or (T, K, 3), got {targets.shape}")

    if on_start is not None:
        on_start(count)
    boxes = _camera_boxes(body, frame_of, batch, targets, camera, out_fps)
    try:
        out.parent.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise VideoWriteError(exc.errno, f"{out.parent}: cannot make the folder ({exc.strerror or exc})") from None
    if out.is_dir():
        raise ValueError(f"output: {out} is a folder, expected a {suffix} file to write")
    partial = out.with_name(f".{out.stem}.{os.getpid()}.partial{suffix}")  # the suffix tells ffmpeg the format
    options: dict[str, Any] = {"macro_block_size": 2, "ffmpeg_log_level": "error"}
    if suffix == ".gif":
        options.update(codec="gif", pix_fmt_out="pal8", output_params=["-filter_complex", _GIF_FILTER])
    else:
        options.update(codec="libx264", pix_fmt_out="yuv420p", quality=7)
    start_time = time.perf_counter()
    # pyrender runs a full gc.collect() for every renderer it deletes (one per frame); frozen objects are not
    # scanned, so the per-frame cost no longer grows with everything the process has loaded.
    was_frozen = gc.get_freeze_count() > 0
    gc.freeze()
    writer = None
    faces = body.faces
    written = False
    try:
        writer = ffmpeg.write_frames(str(partial), (width, height), fps=out_fps, **options)
        writer.send(None)
        for start in range(0, count, batch):
            frames = frame_of[start : start + batch]
            verts, _ = body.evaluate_frames(int(frames[0]), int(frames[-1]) + 1)
            verts = verts[frames - frames[0]]
            for i, k in enumerate(range(start, start + len(frames))):
                lo, hi = boxes[k]
                padded = np.concatenate([verts[i], _box_corners(lo, hi).astype(verts.dtype)])
                extra: dict[str, Any] = {}
                if targets is not None:
                    extra = {
                        "joints": targets[min(int(frames[i]), len(targets) - 1)],
                        "joint_color": _KEYPOINT_COLOR,
                        "alpha": 0.6,
                    }
                image = render_mesh(padded, faces, width=width, height=height, camera=view, color=_BODY_COLOR, **extra)
                try:
                    writer.send(np.ascontiguousarray(image))
                except OSError as exc:  # ffmpeg stopped (it printed why: no space left, ...)
                    raise _write_failed(out, partial, k, count, str(exc).splitlines()[0]) from None
            if progress is not None:
                progress(len(frames))
        writer.close()
        writer = None
        decoded = decoded_frames(partial, suffix)
        if decoded != count:
            raise _write_failed(out, partial, decoded, count, "the file does not decode whole")
        try:
            os.replace(partial, out)
        except OSError as exc:
            raise _write_failed(out, partial, decoded, count, exc.strerror or str(exc)) from None
        written = True
    finally:
        if writer is not None:
            writer.close()
        if not written:
            with contextlib.suppress(OSError):
                partial.unlink()
        if not was_frozen:
            gc.unfreeze()
    return VideoReport(
        path=out, frames=count, fps=out_fps, width=width, height=height, seconds=time.perf_counter() - start_time
    )


def decoded_frames(path: str | Path, suffix: str | None = None) -> int:
    """How many frames of the video at ``path`` decode (0 when it does not decode at all): a GIF's frames
    read with Pillow, an MP4's video packets counted by ffmpeg."""
    path = Path(path)
    suffix = (suffix or path.suffix).lower()
    if suffix == ".gif":
        from PIL import Image

        count = 0
        try:
            with Image.open(path) as img:
                while True:
                    img.load()
                    count += 1
                    img.seek(img.tell() + 1)
        except EOFError:
            return count
        except Exception:  # noqa: BLE001 - truncated or corrupt (Pillow raises IndexError, OSError, ...): frames so far
            return count
    ffmpeg = require("imageio_ffmpeg", "reading videos back")
    try:
        return int(ffmpeg.count_frames_and_secs(str(path))[0])
    except (RuntimeError, OSError, ValueError):
        return 0


def _write_failed(out: Path, partial: Path, frames: int, count: int, why: str) -> VideoWriteError:
    try:
        free = f"; {shutil.disk_usage(out.parent).free:,} bytes free on its disk"
    except OSError:
        free = ""
    return VideoWriteError(
        errno.EIO,
        f"{out}: the video could not be written whole ({why}): {frames} of {count} frames decode back{free}. "
        "Nothing was written there",
    )


def _camera_boxes(
    body: Body, frame_of: np.ndarray, batch: int, targets: np.ndarray | None, camera: str, fps: float
) -> np.ndarray:
    """(N, 2, 3) box to frame for each output frame (lo, hi), from one pass over the motion in batches."""
    count = len(frame_of)
    lo = np.empty((count, 3))
    hi = np.empty((count, 3))
    for start in range(0, count, batch):
        frames = frame_of[start : start + batch]
        verts, _ = body.evaluate_frames(int(frames[0]), int(frames[-1]) + 1)
        verts = verts[frames - frames[0]]
        lo[start : start + len(frames)] = verts.min(axis=1)
        hi[start : start + len(frames)] = verts.max(axis=1)
        if targets is not None:
            kp = targets[np.minimum(frames, len(targets) - 1)]
            lo[start : start + len(frames)] = np.minimum(lo[start : start + len(frames)], kp.min(axis=1))
            hi[start : start + len(frames)] = np.maximum(hi[start : start + len(frames)], kp.max(axis=1))
    if camera == "fixed":
        box = np.stack([lo.min(axis=0), hi.max(axis=0)])
        return np.broadcast_to(box, (count, 2, 3))
    half = 0.5 * (hi - lo).max(axis=0)
    centre = _smooth(0.5 * (lo + hi), max(1, int(round(_SMOOTH_SECONDS * fps))))
    return np.stack([centre - half, centre + half], axis=1)


def _check_installed(module: str, purpose: str) -> None:
    """Raise :class:`MissingDependencyError` (extra ``view``) when ``module`` is not installed, without importing it."""
    import importlib.util

    from smplcore._deps import missing

    try:
        found = importlib.util.find_spec(module) is not None
    except (ImportError, ValueError):  # ValueError: a None placeholder in sys.modules
        found = False
    if not found:
        raise missing(module, purpose, "view")
