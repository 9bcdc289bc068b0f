"""The viewer's GUI panel (viser widgets) and what each widget does to the bodies.

Panels, top to bottom: Body (which body, model type, gender), Shape (betas sliders; the open model's age
in years), Expression, Pose
(a joint picker and its rotation about X, Y, Z in degrees), Motion (play, frame, speed), Display (skeleton,
joint names), Save (mesh, glb). Shape, Expression and Pose follow the selected body and are rebuilt when it
or its model changes.
"""

from __future__ import annotations

import contextlib
import threading
from collections.abc import Iterator
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from scipy.spatial.transform import Rotation

from smplcore.view.bodies import GENDERS, MODEL_TYPES

if TYPE_CHECKING:
    from smplcore.view.viewer import Viewer

BETA_RANGE = 3.0  # sliders span [-3, 3] (standard deviations of the shape space)
PUT_BACK_DELAY = 0.1  # seconds after a refused browser value before its slider is put back (see _checked)
ADULT_AGE = 25.0  # the age slider's position for the open model's default (adult) body
MAX_SLIDERS = 16  # shape / expression sliders shown at most
_ORDER = {"body": 0, "shape": 1, "expression": 2, "pose": 3, "motion": 4, "display": 5, "save": 6}


class Controls:
    """The GUI of a :class:`~smplcore.view.viewer.Viewer`. Attributes hold the widgets (``betas``, ``age``
    (the open model's age slider, None for other models), ``expression``, ``joint``, ``rotation``, ``play``,
    ``frame``, ``speed``, ``skeleton``, ``names``, ``save_mesh``, ``save_glb``, ``status``) so scripts and
    tests can drive them like a user."""

    def __init__(self, viewer: Viewer) -> None:
        self.viewer = viewer
        self.gui = viewer.server.gui
        self.selected = 0
        self._local = threading.local()  # "quiet" per thread: viser runs browsers' callbacks in many threads
        self._edits = threading.RLock()
        self._per_body: list[Any] = []
        self.speed = 1.0
        gui = self.gui
        with gui.add_folder("Body", order=_ORDER["body"]):
            labels = [f"{i}: {b.label}" for i, b in enumerate(viewer.bodies)]
            self.body = gui.add_dropdown("body", labels, initial_value=labels[0], visible=len(labels) > 1)
            self.model = gui.add_dropdown("model", self._model_options(), initial_value=self._body.model.model_type)
            self.gender = gui.add_dropdown("gender", GENDERS, initial_value=self._gender_of(0))
        self.body.on_update(self._quietly(self._on_body))
        self.model.on_update(self._quietly(self._on_model))
        self.gender.on_update(self._quietly(self._on_model))
        self._build_body_panels()

        self.play = self.frame = None
        if viewer.num_frames > 1:
            with gui.add_folder("Motion", order=_ORDER["motion"]):
                self.play = gui.add_checkbox("play", initial_value=False)
                self.frame = gui.add_slider("frame", min=0, max=viewer.num_frames - 1, step=1, initial_value=0)
                self.speed_slider = gui.add_slider("speed", min=0.1, max=4.0, step=0.1, initial_value=1.0)
            self.frame.on_update(self._quietly(self._on_frame))
            self.speed_slider.on_update(self._on_speed)
        with gui.add_folder("Display", order=_ORDER["display"]):
            self.skeleton = gui.add_checkbox("skeleton", initial_value=False)
            self.names = gui.add_checkbox("joint names", initial_value=False)
        self.skeleton.on_update(lambda _: viewer.set_overlays(skeleton=self.skeleton.value))
        self.names.on_update(lambda _: viewer.set_overlays(names=self.names.value))
        with gui.add_folder("Save", order=_ORDER["save"]):
            self.save_mesh = gui.add_button("save mesh (.obj)")
            self.save_glb = gui.add_button("save glb")
            self.status = gui.add_markdown(f"saving to `{viewer.out_dir.resolve()}`")
        self.save_mesh.on_click(lambda event: self._save(event, viewer.save_mesh))
        self.save_glb.on_click(lambda event: self._save(event, viewer.save_glb))

    # ----------------------------------------------------------------------------------------------

    @property
    def _body(self) -> Any:
        return self.viewer.bodies[self.selected]

    @property
    def playing(self) -> bool:
        return self.play is not None and bool(self.play.value)

    def advance(self, step: int) -> None:
        """Move the timeline ``step`` frames on (wrapping around), as playing does."""
        if self.frame is not None:
            self.frame.value = (int(self.frame.value) + step) % self.viewer.num_frames

    @contextlib.contextmanager
    def _silent(self) -> Iterator[None]:
        """Set widgets from the bodies' state without their callbacks acting on it."""
        before = self._quiet
        self._local.quiet = True
        try:
            yield
        finally:
            self._local.quiet = before

    @property
    def _quiet(self) -> bool:
        """Whether this thread is setting widgets from the bodies' state (their callbacks must not act)."""
        return bool(getattr(self._local, "quiet", False))

    def _quietly(self, func: Any) -> Any:
        def callback(event: Any) -> None:
            if not self._quiet:
                func(event)

        return callback

    def _gender_of(self, index: int) -> str:
        gender = self.viewer.genders[index]
        return gender if gender in GENDERS else "neutral"

    def _model_options(self) -> list[str]:
        body = self._body
        base = body.source.model_path or self.viewer.model_path
        current = body.model.model_type
        if base is None:
            options = ["open"]
        elif Path(base).is_dir():
            options = list(MODEL_TYPES)
        else:
            options = ["open", current] if body.source.model_path is None else [current]
        return options if current in options else [current, *options]

    # ----------------------------------------------------------------------------------------------

    def _build_body_panels(self) -> None:
        for handle in self._per_body:
            handle.remove()
        self._per_body = []
        gui, body = self.gui, self._body
        shape = gui.add_folder("Shape", order=_ORDER["shape"])
        self._per_body.append(shape)
        with shape:
            self.betas = [
                gui.add_slider(
                    f"beta {k}", min=-BETA_RANGE, max=BETA_RANGE, step=0.05, initial_value=float(body.betas[k])
                )
                for k in range(min(body.betas.size, MAX_SLIDERS))
            ]
            reset_shape = gui.add_button("reset shape")
            self.age = None
            if body.model.model_type == "open":  # the open model's age axis: infants to elders
                years = self.viewer.ages[self.selected]
                self.age = gui.add_slider(
                    "age (years)", min=1.0, max=90.0, step=0.5, initial_value=ADULT_AGE if years is None else years
                )
        if self.age is not None:
            self.age.on_update(self._quietly(self._set_age))
        for k, slider in enumerate(self.betas):
            slider.on_update(self._quietly(self._coefficient_setter("betas", k, slider)))
        reset_shape.on_click(lambda _: self._reset("betas"))
        self.expression = []
        if body.expression.size:
            folder = gui.add_folder("Expression", order=_ORDER["expression"])
            self._per_body.append(folder)
            with folder:
                self.expression = [
                    gui.add_slider(
                        f"expression {k}",
                        min=-BETA_RANGE,
                        max=BETA_RANGE,
                        step=0.05,
                        initial_value=float(body.expression[k]),
                    )
                    for k in range(min(body.expression.size, MAX_SLIDERS))
                ]
            for k, slider in enumerate(self.expression):
                slider.on_update(self._quietly(self._coefficient_setter("expression", k, slider)))
        pose = gui.add_folder("Pose", order=_ORDER["pose"])
        self._per_body.append(pose)
        with pose:
            self.joint = gui.add_dropdown("joint", body.joint_names, initial_value=body.joint_names[0])
            self.rotation = [
                gui.add_slider(f"rotate {axis} (deg)", min=-180.0, max=180.0, step=1.0, initial_value=0.0)
                for axis in "XYZ"
            ]
            reset_pose = gui.add_button("reset pose")
        self.joint.on_update(lambda _: self._show_joint())
        for slider in self.rotation:
            slider.on_update(self._quietly(self._rotate))
        reset_pose.on_click(lambda _: self._reset("pose"))
        self._show_joint()

    def _coefficient_setter(self, name: str, k: int, slider: Any) -> Any:
        def update(event: Any) -> None:
            with self._edits:  # viser runs a browser's callbacks in a thread pool: one at a time here
                values = getattr(self._body, name)
                value = self._checked(slider, float(values[k]), -BETA_RANGE, BETA_RANGE, event)
                if value is None:
                    return
                values[k] = value
            self._refresh(event)

        return update

    def _set_age(self, event: Any) -> None:
        """Rebuild the selected (open) body at the slider's age, keeping its shape and pose."""
        assert self.age is not None
        with self._edits:
            last = self.viewer.ages[self.selected]
            value = self._checked(self.age, ADULT_AGE if last is None else float(last), 1.0, 90.0, event)
            if value is None:
                return
            self.viewer.switch_model(self.selected, "open", self.gender.value, age=value)
        self._refresh(event)

    def _checked(self, slider: Any, last: float, lo: float, hi: float, event: Any = None) -> float | None:
        """The slider's value if it is a finite number, clamped to [lo, hi] (the slider is set to the clamped
        value); None for NaN, inf or a non-number, the slider being put back to ``last`` (any client could send
        one: it must not reach the bodies, which every client sees). A browser's refused value is put back a
        moment later (:meth:`_put_back`): viser sets a slider from each message in its own thread and runs the
        callbacks in a pool, so a put-back made here could overwrite a valid move that arrived meanwhile."""
        try:
            value = float(slider.value)
        except (TypeError, ValueError):
            value = float("nan")
        if not np.isfinite(value):
            if getattr(event, "client", None) is None:
                self._put_back(slider, last)
            else:
                threading.Timer(PUT_BACK_DELAY, self._put_back, args=(slider, last)).start()
            return None
        if not lo <= value <= hi:
            value = min(max(value, lo), hi)
            with self._silent():
                slider.value = value
        return value

    def _put_back(self, slider: Any, last: float) -> None:
        """Set a slider holding a refused value back to ``last``, unless a valid value came since."""
        with self._edits, self._silent():
            with contextlib.suppress(TypeError, ValueError):
                if np.isfinite(float(slider.value)):
                    return
            slider.value = last

    def _refresh(self, event: Any) -> None:
        """Re-pose the selected body: at once for a change made from Python (scripts see the result), through
        the viewer's merged refresh requests for a change from a browser (bursts of slider moves)."""
        if getattr(event, "client", None) is None:
            self.viewer.refresh(self.selected)
        else:
            self.viewer.request_refresh(self.selected)

    def _on_frame(self, event: Any) -> None:
        assert self.frame is not None
        with self._edits:
            value = self._checked(self.frame, float(self.viewer.current_frame), 0, self.viewer.num_frames - 1, event)
        if value is not None:
            self.viewer.set_frame(int(round(value)), refresh=getattr(event, "client", None) is None)
            if getattr(event, "client", None) is not None:
                self.viewer.request_refresh()

    def _on_speed(self, event: Any) -> None:
        with self._edits:
            value = self._checked(self.speed_slider, self.speed, 0.1, 4.0, event)
            if value is not None:
                self.speed = value

    def _reset(self, what: str) -> None:
        body = self._body
        if what == "betas":
            body.betas[:] = 0.0 if body.track is None else body.track.betas
            sliders = self.betas
            values = body.betas
        else:
            body.full_pose[:] = 0.0
            if body.track is not None:
                body.set_frame(body.frame)
            sliders, values = [], []
        with self._silent():
            for slider, value in zip(sliders, values):
                slider.value = float(value)
        self._show_joint()
        self.viewer.refresh(self.selected)

    def _show_joint(self) -> None:
        """Set the rotation sliders to the picked joint's rotation (intrinsic XYZ Euler angles)."""
        body = self._body
        j = body.joint_names.index(self.joint.value)
        angles = Rotation.from_rotvec(body.full_pose[j].astype(np.float64)).as_euler("XYZ", degrees=True)
        with self._silent():
            for slider, value in zip(self.rotation, angles):
                slider.value = float(np.round(value))

    def _rotate(self, event: Any = None) -> None:
        body = self._body
        j = body.joint_names.index(self.joint.value)
        with self._edits:
            current = Rotation.from_rotvec(body.full_pose[j].astype(np.float64)).as_euler("XYZ", degrees=True)
            angles = [
                self._checked(s, float(np.round(c)), -180.0, 180.0, event) for s, c in zip(self.rotation, current)
            ]
            if any(a is None for a in angles):
                return
            body.full_pose[j] = Rotation.from_euler("XYZ", angles, degrees=True).as_rotvec()
        self._refresh(event)

    def _on_body(self, _: Any) -> None:
        self.selected = [f"{i}: {b.label}" for i, b in enumerate(self.viewer.bodies)].index(self.body.value)
        with self._silent():
            self.model.options = self._model_options()
            self.model.value = self._body.model.model_type
            self.gender.value = self._gender_of(self.selected)
        self._build_body_panels()

    def _on_model(self, _: Any) -> None:
        before = self._body.model.model_type
        try:
            self.viewer.switch_model(
                self.selected, self.model.value, self.gender.value, self.viewer.ages[self.selected]
            )
        except Exception as exc:  # the model's own error (file missing, wrong type): shown, state kept
            self.status.content = f"**could not load {self.model.value} / {self.gender.value}:** {exc}"
            with self._silent():
                self.model.value = before
            return
        self.status.content = f"model: {self.model.value} ({self.gender.value})"
        self._build_body_panels()
        self.viewer.refresh(self.selected)

    def _save(self, event: Any, save: Any) -> None:
        try:
            path = save(self.selected)
        except Exception as exc:  # shown in the panel: a failed save must not kill the viewer
            self.status.content = f"**save failed:** {exc}"
            return
        self.status.content = f"saved `{path}`"
        client = getattr(event, "client", None)
        if client is not None:
            client.send_file_download(path.name, path.read_bytes())
