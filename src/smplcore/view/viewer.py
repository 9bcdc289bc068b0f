"""The browser viewer: bodies in a ``viser`` scene with shape, expression and joint controls, a motion
timeline, skeleton and joint names on demand, model / gender switch and save buttons.

Every update goes through :meth:`Viewer.refresh`: one NumPy forward at batch 1 (the parameters are edited
in place, nothing is rebuilt) and one vertex message to the browser; its durations in milliseconds are kept
in :attr:`Viewer.timings`.
"""

from __future__ import annotations

import collections
import contextlib
import io
import threading
import time
from pathlib import Path
from typing import Any

import numpy as np

from smplcore.view._deps import require
from smplcore.view.bodies import GENDERS, Body, build_model
from smplcore.view.controls import Controls
from smplcore.view.sources import Source, load_keypoints

# Body colours (RGB 0-255): the first body, then the ones beside it.
PALETTE = ((222, 160, 128), (128, 170, 222), (150, 205, 140), (215, 150, 205), (230, 205, 120))
_GAP = 0.25  # metres between neighbouring bodies
LIGHTING = ("studio", "simple")


class Viewer:
    """A viser server showing one or more bodies side by side.

    Parameters
    ----------
    sources : what to show, one body each (:class:`~smplcore.view.sources.Source`, or paths read with
        :func:`~smplcore.view.sources.load_source`); default one open-model body at rest.
    model_path, model_type, gender : the body model for sources that are not model files (default: the
        open model; gender: the motion's, else neutral). With a folder the model switch offers every type.
    port : HTTP port (default 8080; the next free one when taken). ``host`` is 127.0.0.1 unless given.
    keypoints : a (K, 3) / (T, K, 3) array or file of target keypoints, drawn over the first body.
    out_dir : where the save buttons write.
    models : ready :class:`smplcore.BodyModel`\\ s per source (used instead of building one).
    lighting : ``"studio"`` (viser's environment map and shadows) or ``"simple"`` (lights without shadows
        or environment map: much faster where the browser renders WebGL in software, e.g. headless).
    token : the session token a browser must present (see :mod:`smplcore.view.access`): True (default) makes
        a random one, a string is used as given, False asks for none (web pages of a foreign origin are
        refused either way). :attr:`url` is the address to open.
    """

    def __init__(
        self,
        sources: list[Any] | None = None,
        *,
        model_path: str | Path | None = None,
        model_type: str | None = None,
        gender: str | None = None,
        port: int | None = None,
        host: str = "127.0.0.1",
        keypoints: Any = None,
        out_dir: str | Path = ".",
        models: list[Any] | None = None,
        lighting: str = "studio",
        verbose: bool = False,
        token: bool | str = True,
    ) -> None:
        from smplcore.view.access import SessionGate
        from smplcore.view.sources import load_source

        viser = require("viser", "the viewer")
        self.model_path = None if model_path is None else Path(model_path)
        self.model_type = model_type
        self.gender = gender
        self.out_dir = Path(out_dir)
        self.timings: collections.deque[float] = collections.deque(maxlen=2000)
        self._lock = threading.RLock()
        srcs = [s if isinstance(s, Source) else load_source(s) for s in (sources or [Source(label="body")])]
        if lighting not in LIGHTING:
            raise ValueError(f"lighting: expected one of {', '.join(LIGHTING)}, got {lighting!r}")
        self.bodies: list[Body] = []
        self.genders: list[str] = []
        self.ages: list[float | None] = []  # the open model's age per body (None: the adult model)
        for i, src in enumerate(srcs):
            model = models[i] if models and i < len(models) else self._model_for(src)
            self.bodies.append(Body(model, src))
            self.genders.append(self._gender_for(src))
            self.ages.append(None)
        self.keypoints = None if keypoints is None else _keypoints(keypoints)
        # The server starts once every input has loaded: a bad file leaves no server behind.
        self.gate = SessionGate(host=host) if token is True else SessionGate(host=host, token=token or None)
        with _quiet_stdout(not verbose):  # viser prints a banner; a library does not print
            self.server = viser.ViserServer(host=host, port=8080 if port is None else int(port), verbose=verbose)
        try:
            self.gate.install(self.server)  # before any mesh is added: nothing reaches an unchecked client
        except RuntimeError:
            self.server.stop()
            raise
        self.server.scene.set_up_direction("+y")
        if lighting == "simple":
            self.server.scene.configure_environment_map(None)
            self.server.scene.configure_default_lights(True, cast_shadow=False)
            self.server.scene.add_light_hemisphere("/lights/sky", sky_color=(255, 255, 255), ground_color=(90, 80, 70))
        self.show_skeleton = False
        self.show_names = False
        self._nodes: list[dict[str, Any]] = [{} for _ in self.bodies]
        self._offsets = self._layout()
        for i in range(len(self.bodies)):
            self._add_body_nodes(i)
        self._frame_camera()
        self.controls = Controls(self)
        self._stop = threading.Event()
        self._pending: set[int | None] = set()
        self._wake = threading.Event()
        self._player = threading.Thread(target=self._play_loop, name="smplcore-view-player", daemon=True)
        self._player.start()
        self._refresher = threading.Thread(target=self._refresh_loop, name="smplcore-view-refresh", daemon=True)
        self._refresher.start()

    # ----------------------------------------------------------------------------------------------
    # models

    def _model_for(
        self, src: Source, model_type: str | None = None, gender: str | None = None, age: float | None = None
    ) -> Any:
        path = src.model_path if src.model_path is not None else self.model_path
        mtype = model_type if model_type is not None else (None if src.model_path is not None else self.model_type)
        motion_like = src.motion is not None or src.bvh is not None
        betas = 10
        if src.motion is not None:
            betas = max(10, int(np.asarray(src.motion.betas).size))
        elif src.params is not None and "betas" in src.params:
            betas = max(10, int(np.asarray(src.params["betas"]).shape[-1]))
        if mtype == "open":
            path = None
        gender = self._gender_for(src, gender)
        return build_model(path, mtype, gender, num_betas=betas, flat_hand_mean=motion_like, age=age)

    def _gender_for(self, src: Source, gender: str | None = None) -> str:
        """The gender asked for, else the viewer's, else the motion's, else neutral."""
        if gender or self.gender:
            return str(gender or self.gender)
        if src.motion is not None and src.motion.gender in GENDERS:
            return str(src.motion.gender)
        return "neutral"

    def switch_model(self, index: int, model_type: str, gender: str, age: float | None = None) -> None:
        """Give body ``index`` another model (type and gender; the open model at ``age`` years if given),
        keeping its shape and pose where the joints and coefficients match. Raises the model's own error
        when it cannot be loaded."""
        with self._lock:
            old = self.bodies[index]
            model = self._model_for(old.source, model_type, gender, age if model_type == "open" else None)
            new = Body(model, old.source)
            k = min(new.betas.size, old.betas.size)
            new.betas[:k] = old.betas[:k]
            k = min(new.expression.size, old.expression.size)
            new.expression[:k] = old.expression[:k]
            if new.track is None:
                for j, name in enumerate(new.joint_names):
                    if name in old.joint_names:
                        new.full_pose[j] = old.full_pose[old.joint_names.index(name)]
            else:
                new.set_frame(old.frame)
            self.bodies[index] = new
            self.genders[index] = gender
            self.ages[index] = age if model_type == "open" else None
            self._remove_body_nodes(index)
            self._add_body_nodes(index)

    # ----------------------------------------------------------------------------------------------
    # scene

    def _layout(self) -> list[float]:
        """x offset of each body: side by side, left to right, centred on x = 0."""
        widths = []
        for body in self.bodies:
            verts, _ = body.evaluate()
            widths.append((float(verts[:, 0].min()), float(verts[:, 0].max())))
        offsets, x = [], 0.0
        for lo, hi in widths:
            offsets.append(x - lo)
            x += (hi - lo) + _GAP
        total = x - _GAP
        return [o - 0.5 * total for o in offsets]

    def _color(self, index: int) -> tuple[int, int, int]:
        return PALETTE[index % len(PALETTE)]

    def _mesh_opacity(self, index: int) -> float | None:
        """Translucent when what is inside must show through: the bones, or the target keypoints (body 0),
        which mostly lie inside the body."""
        inside = self.show_skeleton or (index == 0 and self.keypoints is not None)
        return 0.45 if inside else None

    def _add_body_nodes(self, index: int) -> None:
        scene = self.server.scene
        body = self.bodies[index]
        root = f"/bodies/{index}"
        verts, joints = body.evaluate()
        nodes: dict[str, Any] = {"frame": scene.add_frame(root, show_axes=False, position=(self._offsets[index], 0, 0))}
        nodes["mesh"] = scene.add_mesh_simple(
            f"{root}/mesh",
            verts,
            body.faces,
            color=self._color(index),
            opacity=self._mesh_opacity(index),
        )
        parents = body.model.parents
        nodes["bones"] = np.array([(j, p) for j, p in enumerate(parents) if p >= 0], dtype=np.int64).reshape(-1, 2)
        nodes["skeleton"] = scene.add_line_segments(
            f"{root}/skeleton",
            joints[nodes["bones"]],
            (30, 30, 30),
            thickness=4.0,
            thickness_units="screen",
            visible=self.show_skeleton,
        )
        nodes["joints"] = scene.add_point_cloud(
            f"{root}/joints",
            joints,
            (200, 40, 30),
            point_size=0.02,
            point_shape="circle",
            precision="float32",
            visible=self.show_skeleton,
        )
        nodes["names"] = [
            scene.add_label(f"{root}/names/{j}", name, position=joints[j], visible=self.show_names)
            for j, name in enumerate(body.joint_names)
        ]
        if index == 0 and self.keypoints is not None:
            nodes["keypoints"] = scene.add_point_cloud(
                f"{root}/keypoints",
                self.keypoints[min(body.frame, len(self.keypoints) - 1)],
                (20, 160, 60),
                point_size=0.03,
                point_shape="diamond",
                precision="float32",
            )
        self._nodes[index] = nodes

    def _remove_body_nodes(self, index: int) -> None:
        nodes = self._nodes[index]
        nodes["frame"].remove()  # children go with it
        self._nodes[index] = {}

    def _frame_camera(self) -> None:
        lo = np.full(3, np.inf)
        hi = np.full(3, -np.inf)
        for body, x in zip(self.bodies, self._offsets):
            verts, _ = body.evaluate()
            lo = np.minimum(lo, verts.min(0) + (x, 0, 0))
            hi = np.maximum(hi, verts.max(0) + (x, 0, 0))
        centre = 0.5 * (lo + hi)
        size = float(max(hi[1] - lo[1], hi[0] - lo[0], 0.2))
        cam = self.server.initial_camera
        cam.look_at = tuple(centre)
        cam.position = (float(centre[0]), float(centre[1] + 0.15 * size), float(hi[2] + 1.1 * size))
        cam.up = (0.0, 1.0, 0.0)
        self.server.scene.add_grid(
            "/floor",
            width=max(4.0, 2 * size),
            height=max(4.0, 2 * size),
            plane="xz",
            position=(float(centre[0]), float(lo[1]), 0.0),
            cell_size=0.25,
        )

    def refresh(self, index: int | list[int] | None = None) -> None:
        """Re-pose body ``index`` (a list of them; all with None) and send its mesh (and skeleton, names,
        keypoints when shown)."""
        indices = range(len(self.bodies)) if index is None else ([index] if isinstance(index, int) else index)
        with self._lock:
            for i in indices:
                start = time.perf_counter()
                body, nodes = self.bodies[i], self._nodes[i]
                verts, joints = body.evaluate()
                with self.server.atomic():
                    nodes["mesh"].vertices = verts
                    if self.show_skeleton:
                        nodes["skeleton"].points = joints[nodes["bones"]].astype(np.float32)
                        nodes["joints"].points = joints.astype(np.float32)
                    if self.show_names:
                        for label, point in zip(nodes["names"], joints):
                            label.position = point
                    if "keypoints" in nodes and (kp := self.keypoints) is not None:
                        nodes["keypoints"].points = kp[min(body.frame, len(kp) - 1)].astype(np.float32)
                self.timings.append(1e3 * (time.perf_counter() - start))

    def request_refresh(self, index: int | None = None) -> None:
        """Refresh body ``index`` (all with None) soon, in the viewer's refresh thread. Requests made while a
        refresh runs are merged: a burst of slider moves costs one refresh with the latest values, not one
        per move, and never queues work that would delay the others or Ctrl-C."""
        self._pending.add(index)
        self._wake.set()

    def _refresh_loop(self) -> None:
        while not self._stop.is_set():
            if not self._wake.wait(timeout=0.2):
                continue
            self._wake.clear()
            pending, self._pending = self._pending, set()
            try:
                self.refresh(None if None in pending else sorted(i for i in pending if i is not None))
            except Exception as exc:  # noqa: BLE001 - a failed refresh must not end the thread (shown once)
                from smplcore.errors import warn

                warn(f"viewer: a refresh failed ({type(exc).__name__}: {exc})")

    def set_overlays(self, skeleton: bool | None = None, names: bool | None = None) -> None:
        """Show or hide the skeleton (bones and joint dots) and the joint names of every body."""
        with self._lock:
            if skeleton is not None:
                self.show_skeleton = bool(skeleton)
            if names is not None:
                self.show_names = bool(names)
            for index, nodes in enumerate(self._nodes):
                nodes["mesh"].opacity = self._mesh_opacity(index)
                nodes["skeleton"].visible = self.show_skeleton
                nodes["joints"].visible = self.show_skeleton
                for label in nodes["names"]:
                    label.visible = self.show_names
            self.refresh()

    # ----------------------------------------------------------------------------------------------
    # motion

    @property
    def num_frames(self) -> int:
        """Frames of the timeline: the longest track (at its own frame rate), 1 without tracks."""
        return max([b.num_frames for b in self.bodies] + ([len(self.keypoints)] if self.keypoints is not None else []))

    @property
    def fps(self) -> float:
        rates = [b.track.fps for b in self.bodies if b.track is not None]
        return rates[0] if rates else 30.0

    @property
    def current_frame(self) -> int:
        """The timeline frame shown (the first body's)."""
        return int(self.bodies[0].frame) if self.bodies else 0

    def set_frame(self, frame: int, refresh: bool = True) -> None:
        """Show timeline frame ``frame`` on every body (each track at its own frame rate, held at its end);
        ``refresh=False`` sets the bodies' state only (then :meth:`request_refresh` sends it)."""
        with self._lock:
            for body in self.bodies:
                if body.track is not None:
                    body.set_frame(round(frame * body.track.fps / self.fps))
                else:
                    body.frame = frame
            if refresh:
                self.refresh()

    def _play_loop(self) -> None:
        last = time.perf_counter()
        clock = 0.0
        while not self._stop.is_set():
            time.sleep(1.0 / 60.0)
            now = time.perf_counter()
            dt, last = now - last, now
            ctl = getattr(self, "controls", None)
            if ctl is None or not ctl.playing or self.num_frames < 2:
                clock = 0.0
                continue
            clock += dt * ctl.speed * self.fps
            if clock >= 1.0:
                step, clock = int(clock), clock - int(clock)
                ctl.advance(step)

    # ----------------------------------------------------------------------------------------------
    # saving

    def save_mesh(self, index: int = 0, path: str | Path | None = None) -> Path:
        """Write body ``index`` as it is now to ``path`` (default ``OUT_DIR/<name>_frame<k>.obj``)."""
        from smplcore.export import save_mesh

        body = self.bodies[index]
        with self._lock:
            verts, _ = body.evaluate()
        out = Path(path) if path is not None else self.out_dir / f"{_stem(body.label)}_frame{body.frame}.obj"
        return save_mesh(out, verts, body.faces)

    def save_glb(self, index: int = 0, path: str | Path | None = None) -> Path:
        """Write body ``index`` as a rigged glTF binary: its whole motion with the current shape, or the
        current pose (default ``OUT_DIR/<name>.glb``)."""
        from smplcore.export import save_glb

        body = self.bodies[index]
        with self._lock:
            params = _track_params(body) if body.track is not None else body.params()
        out = Path(path) if path is not None else self.out_dir / f"{_stem(body.label)}.glb"
        save_glb(out, body.model, params, fps=body.track.fps if body.track is not None else None)
        return out

    # ----------------------------------------------------------------------------------------------

    @property
    def port(self) -> int:
        return int(self.server.get_port())

    @property
    def url(self) -> str:
        """The address to open in a browser (with the session token, unless the viewer was made without)."""
        return self.gate.url(self.port)

    def close(self) -> None:
        """Stop the player, the refresh thread and the server."""
        self._stop.set()
        self._wake.set()
        self._player.join(timeout=2.0)
        self._refresher.join(timeout=2.0)
        with _quiet_stdout(True):
            self.server.stop()

    def __enter__(self) -> Viewer:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def _quiet_stdout(quiet: bool) -> contextlib.AbstractContextManager[Any]:
    return contextlib.redirect_stdout(io.StringIO()) if quiet else contextlib.nullcontext()


def _track_params(body: Body) -> dict[str, np.ndarray]:
    """The body's whole track as model keyword arrays (T, n), with its current shape."""
    from smplcore.view.bodies import _block_offsets

    t = body.track
    assert t is not None
    params = {block: t.poses[:, a:b].reshape(t.num_frames, -1) for block, (a, b) in _block_offsets(body.model).items()}
    params["transl"] = t.transl
    params["betas"] = body.betas[None].astype(np.float64)
    if t.expression is not None:
        params["expression"] = t.expression
    return params


def _stem(label: str) -> str:
    stem = Path(label).stem or "body"
    return "".join(c if c.isalnum() or c in "-_" else "_" for c in stem)


def _keypoints(value: Any) -> np.ndarray:
    if isinstance(value, (str, Path)):
        return load_keypoints(value)
    arr = np.asarray(value, dtype=np.float64)
    if arr.ndim not in (2, 3) or arr.shape[-1] != 3:
        from smplcore.errors import ShapeError

        raise ShapeError(f"keypoints: expected shape (K, 3) or (T, K, 3), got {arr.shape}")
    return arr[None] if arr.ndim == 2 else arr
