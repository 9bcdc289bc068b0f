"""The contenders: one adapter per library and backend, all running the same bodies.

Every adapter takes the same canonical parameters (NumPy float32, smplx's names and layout:
``betas`` (B, 10), ``global_orient`` (B, 3), ``body_pose``, ``left_hand_pose``/``right_hand_pose``
(B, 45, full axis-angle, flat hand mean), ``jaw_pose``/``leye_pose``/``reye_pose``, ``expression``
(B, 10)) and offers:

* ``forward(x)`` -> (vertices, joints): the posed mesh and the joints, no autograd;
* ``joints(x)`` -> joints: the cheapest joints call the library has (see ``joints_note``);
* ``fwd_bwd(x)``: forward with autograd through pose and shape, ``(vertices.sum() + joints.sum())``
  backward (torch adapters only).

``prepare(params, grad)`` turns the canonical parameters into the adapter's inputs once, outside the
timed region.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from fixtures import ModelFiles


@dataclass(frozen=True)
class ModelInfo:
    key: str
    label: str
    num_verts: int
    num_joints: int  # skeleton joints J
    num_coeffs: int  # K: shape (+ expression) coefficients evaluated by smplx / smplcore
    num_pose_features: int  # P = 9 (J - 1), 0 when the model has no pose correctives
    body_joints: int  # joints in body_pose
    hands: bool
    face: bool


def model_info(key: str) -> ModelInfo:
    if key == "smpl":
        return ModelInfo("smpl", "SMPL", 6890, 24, 10, 207, 23, False, False)
    if key == "smplh":
        return ModelInfo("smplh", "SMPL+H", 6890, 52, 10, 459, 21, True, False)
    if key == "smplx":
        return ModelInfo("smplx", "SMPL-X", 10475, 55, 20, 486, 21, True, True)
    if key == "open":
        from fixtures import OPEN_MODEL

        d = np.load(OPEN_MODEL, allow_pickle=False)
        num_joints = int(d["parents"].shape[0])
        pose = 9 * (num_joints - 1) if "posedirs" in d.files and np.any(d["posedirs"]) else 0
        return ModelInfo(
            "open", "open", int(d["v_template"].shape[0]), num_joints, 10, pose, num_joints - 1, False, False
        )
    raise ValueError(key)


def canonical_params(info: ModelInfo, batch: int, seed: int = 0) -> dict[str, np.ndarray]:
    rng = np.random.default_rng([seed, batch])

    def aa(n: int, scale: float = 0.3) -> np.ndarray:
        return rng.normal(0.0, scale, (batch, 3 * n)).astype(np.float32)

    p = {
        "betas": rng.normal(0.0, 1.0, (batch, 10)).astype(np.float32),
        "global_orient": aa(1),
        "body_pose": aa(info.body_joints),
    }
    if info.hands:
        p["left_hand_pose"], p["right_hand_pose"] = aa(15), aa(15)
    if info.face:
        p["jaw_pose"], p["leye_pose"], p["reye_pose"] = aa(1, 0.1), aa(1, 0.1), aa(1, 0.1)
        p["expression"] = np.zeros((batch, 10), np.float32)  # smplfitter has no separate expression input
    return p


def full_pose(params: dict[str, np.ndarray]) -> np.ndarray:
    """(B, 3 J) axis-angle in the kinematic order of the official files."""
    order = [
        "global_orient",
        "body_pose",
        "jaw_pose",
        "leye_pose",
        "reye_pose",
        "left_hand_pose",
        "right_hand_pose",
    ]
    return np.concatenate([params[k] for k in order if k in params], axis=1)


def _torch():
    import torch

    return torch


#: Where the torch contenders run (``bench/forward.py --device``).
DEVICE = "cpu"


def sync() -> None:
    """Wait for the device's queued work (timings on a GPU)."""
    if DEVICE != "cpu":
        _torch().cuda.synchronize()


class Contender:
    name = ""
    kind = "torch"  # or "numpy"
    library = ""
    joints_note = ""
    grad = True

    def __init__(self, info: ModelInfo, files: ModelFiles) -> None:
        self.info, self.files = info, files

    # Torch adapters: tensors, grad leaves when asked.
    def _tensors(self, arrays: dict[str, np.ndarray], grad: bool) -> dict[str, Any]:
        torch = _torch()
        out = {}
        for k, v in arrays.items():
            t = torch.from_numpy(np.ascontiguousarray(v)).to(DEVICE)
            if grad and k not in ("expression",):
                t.requires_grad_(True)
            out[k] = t
        return out

    def prepare(self, params: dict[str, np.ndarray], grad: bool = False) -> Any:
        raise NotImplementedError

    def forward(self, x: Any) -> tuple[Any, Any]:
        raise NotImplementedError

    def joints(self, x: Any) -> Any:
        raise NotImplementedError

    def _run(self, x: Any) -> tuple[Any, Any]:
        """Forward with autograd (torch adapters)."""
        raise NotImplementedError

    def fwd_bwd(self, x: Any) -> None:
        verts, joints = self._run(x)
        (verts.sum() + joints.sum()).backward()
        for t in _leaves(x):
            t.grad = None


def _leaves(x: Any) -> list:
    torch = _torch()
    vals = x.values() if isinstance(x, dict) else x
    return [v for v in vals if isinstance(v, torch.Tensor) and v.requires_grad]


# ------------------------------------------------------------------------------------------------
# smplcore


def _smplx_style_options(info: ModelInfo) -> dict:
    opts: dict = {"num_betas": 10}
    if info.hands:
        opts.update(use_pca=False, flat_hand_mean=True)
    if info.face:
        opts.update(num_expression_coeffs=10)
    return opts


class SmplcoreTorch(Contender):
    name, kind, library = "smplcore-torch", "torch", "smplcore"
    joints_note = "return_verts=False (skeleton + extra vertex joints, no mesh)"
    skinning = "lbs"

    def __init__(self, info, files):
        super().__init__(info, files)
        import smplcore

        opts = {**_smplx_style_options(info), "skinning": self.skinning}
        if info.key == "open":
            self.model = smplcore.create(model_type="open", create_transl=False, **opts)
        else:
            self.model = smplcore.create(
                str(files.smplx_root),
                model_type=files.smplx_type,
                gender="neutral",
                ext=files.ext,
                create_transl=False,
                **opts,
            )
        self.model.requires_grad_(False)
        self.model.to(DEVICE)

    def prepare(self, params, grad=False):
        return self._tensors(params, grad)

    def _run(self, x):
        out = self.model(**x, return_verts=True)
        return out.vertices, out.joints

    def forward(self, x):
        with _torch().no_grad():
            return self._run(x)

    def joints(self, x):
        with _torch().no_grad():
            return self.model(**x, return_verts=False).joints


class SmplcoreNumpy(Contender):
    name, kind, library, grad = "smplcore-numpy", "numpy", "smplcore", False
    joints_note = "return_verts=False (skeleton + extra vertex joints, no mesh)"
    skinning = "lbs"

    def __init__(self, info, files):
        super().__init__(info, files)
        import smplcore

        opts = {**_smplx_style_options(info), "skinning": self.skinning}
        if info.key == "open":
            self.model = smplcore.BodyModel(model_type="open", dtype=np.float32, **opts)
        else:
            self.model = smplcore.BodyModel(str(files.file), gender="neutral", dtype=np.float32, **opts)

    def prepare(self, params, grad=False):
        return dict(params)

    def forward(self, x):
        out = self.model(**x, return_verts=True)
        return out.vertices, out.joints

    def joints(self, x):
        return self.model(**x, return_verts=False).joints


# ------------------------------------------------------------------------------------------------
# smplx 0.1.28


class Smplx(Contender):
    name, kind, library = "smplx", "torch", "smplx"
    joints_note = "full forward (smplx has no joints-only path)"

    def __init__(self, info, files):
        super().__init__(info, files)
        import smplx

        self.model = smplx.create(
            str(files.smplx_root),
            model_type=files.smplx_type,
            gender="neutral",
            ext=files.ext,
            create_transl=False,
            **_smplx_style_options(info),
        )
        self.model.requires_grad_(False)
        self.model.to(DEVICE)

    def prepare(self, params, grad=False):
        return self._tensors(params, grad)

    def _run(self, x):
        out = self.model(**x, return_verts=True)
        return out.vertices, out.joints

    def forward(self, x):
        with _torch().no_grad():
            return self._run(x)

    def joints(self, x):
        with _torch().no_grad():
            return self.model(**x, return_verts=False).joints


# ------------------------------------------------------------------------------------------------
# body-models 0.26.2


class BodyModels(Contender):
    """body-models, public API: ``prepare_identity`` + ``prepare_pose`` once, then the mesh from them.

    (Its ``forward_vertices`` and ``forward_skeleton`` would each run the kinematic chain; sharing the
    prepared pose gives body-models its best case for "vertices + joints".) Joints-only is
    ``forward_skeleton``: skeleton joints, no extra vertex joints.
    """

    library = "body-models"
    joints_note = "forward_skeleton (skeleton joints only, no vertex joints)"

    def __init__(self, info, files):
        super().__init__(info, files)
        import importlib

        backend = "torch" if self.kind == "torch" else "numpy"
        sub = {"smpl": "smpl", "open": "smpl", "smplh": "smplh", "smplx": "smplx"}[info.key]
        cls_name = {"smpl": "SMPL", "smplh": "SMPLH", "smplx": "SMPLX"}[sub]
        cls = getattr(importlib.import_module(f"body_models.{sub}.{backend}"), cls_name)
        kwargs = {"flat_hand_mean": True} if info.hands else {}
        self.model = cls(model_path=str(files.file), **kwargs)
        if self.kind == "torch":
            self.model.requires_grad_(False)

    def _inputs(self, params):
        b = params["betas"].shape[0]
        x = {
            "body_pose": params["body_pose"].reshape(b, -1, 3),
            "pelvis_rotation": params["global_orient"],
            "shape": params["betas"],
        }
        if self.info.hands:
            x["hand_pose"] = np.concatenate([params["left_hand_pose"], params["right_hand_pose"]], 1).reshape(b, 30, 3)
        if self.info.face:
            x["head_pose"] = np.concatenate([params["jaw_pose"], params["leye_pose"], params["reye_pose"]], 1).reshape(
                b, 3, 3
            )
            x["expression"] = params["expression"]
        return x

    def prepare(self, params, grad=False):
        x = self._inputs(params)
        return self._tensors(x, grad) if self.kind == "torch" else x

    def _split(self, x):
        ident = {k: x[k] for k in ("shape", "expression") if k in x}
        pose = {k: v for k, v in x.items() if k not in ident}
        return ident, pose

    def _run(self, x):
        ident, pose = self._split(x)
        identity = self.model.prepare_identity(**ident)
        prepared = self.model.prepare_pose(**pose, identity=identity)
        verts = self.model._deform_vertices(identity, prepared, None, None, None)
        joints = prepared["skeleton_transforms"][..., :3, 3]
        return verts, joints

    def forward(self, x):
        if self.kind == "torch":
            with _torch().no_grad():
                return self._run(x)
        return self._run(x)

    def joints(self, x):
        def run():
            return self.model.forward_skeleton(**x)[..., :3, 3]

        if self.kind == "torch":
            with _torch().no_grad():
                return run()
        return run()


class BodyModelsTorch(BodyModels):
    name, kind = "body-models-torch", "torch"


class BodyModelsNumpy(BodyModels):
    name, kind, grad = "body-models-numpy", "numpy", False


# ------------------------------------------------------------------------------------------------
# smplfitter 0.6.0


class Smplfitter(Contender):
    library = "smplfitter"
    joints_note = "return_vertices=False (skeleton joints only, no vertex joints)"

    def __init__(self, info, files):
        super().__init__(info, files)
        if self.kind == "torch":
            from smplfitter.pt import BodyModel
        else:
            from smplfitter.np import BodyModel
        name = {"smpl": "smpl", "open": "smpl", "smplh": "smplh", "smplx": "smplx"}[info.key]
        self.model = BodyModel(name, files.smplfitter_gender, model_root=str(files.smplfitter_root), num_betas=10)
        if self.kind == "torch":
            self.model.requires_grad_(False)

    def prepare(self, params, grad=False):
        x = {"pose_rotvecs": full_pose(params), "shape_betas": params["betas"]}
        return self._tensors(x, grad) if self.kind == "torch" else x

    def _run(self, x):
        out = self.model(**x)
        return out["vertices"], out["joints"]

    def forward(self, x):
        if self.kind == "torch":
            with _torch().no_grad():
                return self._run(x)
        return self._run(x)

    def joints(self, x):
        if self.kind == "torch":
            with _torch().no_grad():
                return self.model(**x, return_vertices=False)["joints"]
        return self.model(**x, return_vertices=False)["joints"]


class SmplfitterTorch(Smplfitter):
    name, kind = "smplfitter-torch", "torch"


class SmplfitterNumpy(Smplfitter):
    name, kind, grad = "smplfitter-numpy", "numpy", False


class _Compiled:
    """Mixed into a torch contender: its module under ``torch.compile`` (default Inductor; the first
    call of each shape compiles, which the warm-up call absorbs)."""

    def __init__(self, info, files):
        super().__init__(info, files)
        self.model = _torch().compile(self.model)


class SmplcoreTorchCompiled(_Compiled, SmplcoreTorch):
    name = "smplcore-torch-compiled"
    joints_note = SmplcoreTorch.joints_note + ", torch.compile"


class SmplxCompiled(_Compiled, Smplx):
    name = "smplx-compiled"
    joints_note = Smplx.joints_note + ", torch.compile"


class SmplcoreTorchDqs(SmplcoreTorch):
    name, skinning = "smplcore-torch-dqs", "dqs"
    joints_note = SmplcoreTorch.joints_note + ", skinning='dqs'"


class SmplcoreNumpyDqs(SmplcoreNumpy):
    name, skinning = "smplcore-numpy-dqs", "dqs"
    joints_note = SmplcoreNumpy.joints_note + ", skinning='dqs'"


#: Contenders added by ``bench/forward.py --dqs``: smplcore with dual-quaternion skinning.
DQS = {c.name: c for c in (SmplcoreTorchDqs, SmplcoreNumpyDqs)}

#: Contenders added by ``bench/forward.py --compile``.
COMPILED = {c.name: c for c in (SmplcoreTorchCompiled, SmplxCompiled)}

CONTENDERS: dict[str, type[Contender]] = {
    c.name: c
    for c in (
        SmplcoreTorch,
        SmplcoreNumpy,
        Smplx,
        BodyModelsNumpy,
        BodyModelsTorch,
        SmplfitterNumpy,
        SmplfitterTorch,
    )
}


def to_numpy(a: Any) -> np.ndarray:
    if hasattr(a, "detach"):
        return a.detach().cpu().numpy()
    return np.asarray(a)
