"""Helpers shared by the export tests: test motions, the model without pose correctives, the Khronos glTF
validator (installed from npm on first use) and an independent glTF reader + skinner (pygltflib + NumPy)."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

import smplcore
from smplcore.motion import POSE_WIDTH, Motion

OPEN_MODEL = Path(smplcore.__file__).resolve().parent / "data" / "open_model.npz"
HERE = Path(__file__).resolve().parent
VALIDATOR_DIR = Path(os.environ.get("SMPLCORE_TEST_CACHE", Path.home() / ".cache" / "smplcore-tests"))


def open_model(**options):
    if not OPEN_MODEL.exists():
        pytest.skip(f"the open model is not built yet ({OPEN_MODEL} is absent)")
    return smplcore.BodyModel(model_type="open", **options)


def make_motion(
    model_type: str = "smpl",
    seconds: float = 2.0,
    fps: float = 30.0,
    seed: int = 0,
    num_betas: int = 10,
    amplitude: float = 0.35,
    expression: int = 0,
) -> Motion:
    """A smooth, walk-like test motion: every joint swings sinusoidally, the root turns and travels."""
    rng = np.random.default_rng(seed)
    frames = int(round(seconds * fps))
    t = np.arange(frames)[:, None] / fps
    width = POSE_WIDTH[model_type]
    amp = rng.normal(0.0, amplitude, (1, width))
    phase = rng.uniform(0.0, 2 * np.pi, (1, width))
    freq = rng.uniform(0.3, 1.2, (1, width))
    poses = amp * np.sin(2 * np.pi * freq * t + phase)
    poses[:, :3] = np.c_[0.2 * np.sin(t), 1.5 * t, 0.1 * np.cos(2 * t)]  # the root turns about +Y
    trans = np.c_[0.8 * t[:, 0], 0.05 * np.sin(4 * t[:, 0]), 0.3 * t[:, 0]]
    expr = rng.normal(0.0, 1.0, (1, expression)) * np.sin(3 * t) if expression else None
    return Motion(
        poses=poses,
        trans=trans,
        betas=rng.normal(0.0, 1.0, num_betas),
        fps=fps,
        model_type=model_type,
        gender="neutral",
        expression=expr,
    )


def without_correctives(model: smplcore.BodyModel, **options) -> smplcore.BodyModel:
    """The same model (same file, same options) with the pose-corrective blend shapes removed."""
    data = model.setup.data.replace(posedirs=None)
    setup = model.setup
    return smplcore.BodyModel(
        data=data,
        num_betas=model.num_betas,
        num_expression_coeffs=max(model.num_expression_coeffs, 1),
        use_pca=setup.use_pca,
        num_pca_comps=setup.num_pca_comps,
        flat_hand_mean=setup.flat_hand_mean,
        **options,
    )


# --------------------------------------------------------------------------------------------------
# Khronos glTF validator


NODE_PACKAGES = {
    "gltf-validator": "2.0.0-dev.3.10",
    "three": "0.170.0",
    "@pixiv/three-vrm": "3.5.5",
    "@pixiv/three-vrm-animation": "3.5.5",
}


def node_package(name: str) -> tuple[str, Path]:
    """``(node executable, node_modules dir)`` with npm package ``name`` installed into ``VALIDATOR_DIR`` on
    first use (the pinned version); skips when node or npm is absent. Every pinned package is installed in
    one npm call: an ``npm install --no-save`` of one package removes the others it does not know of."""
    node, npm = shutil.which("node"), shutil.which("npm")
    if node is None or npm is None:
        pytest.skip(f"{name} (npm) needs node and npm, which are not installed")
    modules = VALIDATOR_DIR / "node_modules"
    if not (modules / name / "package.json").exists():
        VALIDATOR_DIR.mkdir(parents=True, exist_ok=True)
        result = subprocess.run(
            [
                npm,
                "install",
                "--no-audit",
                "--no-fund",
                "--no-save",
                "--prefix",
                str(VALIDATOR_DIR),
                *(f"{n}@{v}" for n, v in NODE_PACKAGES.items()),
            ],
            capture_output=True,
            text=True,
            timeout=600,
        )
        if result.returncode != 0 or not (modules / name / "package.json").exists():
            pytest.fail(f"npm install {name} failed:\n{result.stdout}\n{result.stderr}")
    return node, modules


def validate(path: Path) -> dict:
    """The validator's JSON report of ``path``."""
    node, modules = node_package("gltf-validator")
    env = dict(os.environ, NODE_PATH=str(modules))
    result = subprocess.run(
        [node, str(HERE / "gltf_validate.js"), str(path)],
        capture_output=True,
        text=True,
        env=env,
        timeout=300,
    )
    assert result.returncode == 0, f"validator failed: {result.stderr}"
    return json.loads(result.stdout)


def three_js(path: Path, fps: float, frames: list[int]) -> dict:
    """three.js (GLTFLoader + AnimationMixer) playing ``path``: skinned ``vertices`` and ``bones`` world
    positions
    at ``frames`` (dicts keyed by the frame number as a string)."""
    node, modules = node_package("three")
    result = subprocess.run(
        [
            node,
            str(HERE / "three_check.mjs"),
            str(modules),
            str(path),
            str(fps),
            ",".join(str(k) for k in frames),
        ],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert result.returncode == 0, f"three.js failed: {result.stderr}"
    return json.loads(result.stdout)


def issues(report: dict, max_severity: int = 0) -> list[dict]:
    """Messages of ``report`` with severity <= ``max_severity`` (0 errors, 1 warnings, 2 infos, 3 hints)."""
    return [m for m in report["issues"]["messages"] if m["severity"] <= max_severity]


# --------------------------------------------------------------------------------------------------
# An independent glTF reader: pygltflib for the arrays, skinning in a few lines of NumPy


_COMPONENTS = {5126: np.float32, 5121: np.uint8, 5123: np.uint16, 5125: np.uint32}
_WIDTH = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4, "MAT4": 16}


class GlbReader:
    def __init__(self, path: Path) -> None:
        import pygltflib

        path = Path(path)  # .vrm / .vrma are glb files under another suffix
        self.gltf = (
            pygltflib.GLTF2().load(str(path))
            if path.suffix.lower() in (".glb", ".gltf")
            else (pygltflib.GLTF2().load_binary(str(path)))
        )
        self.blob = self.gltf.binary_blob()

    def array(self, index: int) -> np.ndarray:
        acc = self.gltf.accessors[index]
        view = self.gltf.bufferViews[acc.bufferView]
        dtype = np.dtype(_COMPONENTS[acc.componentType])
        width = _WIDTH[acc.type]
        start = (view.byteOffset or 0) + (acc.byteOffset or 0)
        stride = view.byteStride or dtype.itemsize * width
        rows = (
            [np.frombuffer(self.blob, dtype, count=width, offset=start + i * stride) for i in range(acc.count)]
            if view.byteStride
            else None
        )
        arr = (
            np.stack(rows)
            if rows
            else np.frombuffer(self.blob, dtype, count=acc.count * width, offset=start).reshape(acc.count, width)
        )
        if acc.normalized:
            arr = arr / np.iinfo(dtype).max
        return arr.astype(np.float64) if dtype.kind == "f" or acc.normalized else arr.astype(np.int64)

    def times(self) -> np.ndarray:
        anim = self.gltf.animations[0]
        return self.array(anim.samplers[0].input)[:, 0]

    def node_trs(self, frame: int) -> tuple[np.ndarray, np.ndarray]:
        """Local translation (N, 3) and rotation (N, 4; x y z w) of every node at keyframe ``frame``."""
        nodes = self.gltf.nodes
        trans = np.array([n.translation or [0.0, 0.0, 0.0] for n in nodes], dtype=np.float64)
        quat = np.array([n.rotation or [0.0, 0.0, 0.0, 1.0] for n in nodes], dtype=np.float64)
        if not self.gltf.animations:  # e.g. a .vrm avatar: its rest pose
            return trans, quat
        anim = self.gltf.animations[0]
        for ch in anim.channels:
            sampler = anim.samplers[ch.sampler]
            out = self.array(sampler.output)
            if ch.target.path == "translation":
                trans[ch.target.node] = out[frame]
            elif ch.target.path == "rotation":
                quat[ch.target.node] = out[frame]
        return trans, quat

    def morph_weights(self, frame: int) -> np.ndarray | None:
        mesh = self.gltf.meshes[0]
        if not mesh.primitives[0].targets:
            return None
        weights = np.array(mesh.weights or [0.0] * len(mesh.primitives[0].targets))
        anim = self.gltf.animations[0]
        for ch in anim.channels:
            if ch.target.path == "weights":
                out = self.array(anim.samplers[ch.sampler].output).reshape(-1, len(weights))
                weights = out[frame]
        return weights

    def world_matrices(self, frame: int) -> np.ndarray:
        """(N, 4, 4) world matrix of every node at keyframe ``frame``."""
        trans, quat = self.node_trs(frame)
        local = np.tile(np.eye(4), (len(trans), 1, 1))
        local[:, :3, :3] = quat_to_matrix(quat)
        local[:, :3, 3] = trans
        world = np.zeros_like(local)
        done = np.zeros(len(trans), bool)

        def visit(i: int, parent: np.ndarray) -> None:
            world[i] = parent @ local[i]
            done[i] = True
            for child in self.gltf.nodes[i].children or []:
                visit(child, world[i])

        for root in self.gltf.scenes[self.gltf.scene or 0].nodes:
            visit(root, np.eye(4))
        assert done.all()
        return world

    def skinned_vertices(self, frame: int) -> np.ndarray:
        """(V, 3) vertices of the skinned mesh at keyframe ``frame`` (glTF skinning: morph, then skin)."""
        prim = self.gltf.meshes[0].primitives[0]
        attrs = prim.attributes
        verts = self.array(attrs.POSITION)
        weights = self.morph_weights(frame)
        if weights is not None:
            for w, target in zip(weights, prim.targets, strict=True):
                if w:
                    index = target["POSITION"] if isinstance(target, dict) else target.POSITION
                    verts = verts + w * self.array(index)
        skin = self.gltf.skins[0]
        ibm = self.array(skin.inverseBindMatrices).reshape(-1, 4, 4).transpose(0, 2, 1)  # column-major
        joint_mats = self.world_matrices(frame)[skin.joints] @ ibm
        blended = np.zeros((len(verts), 4, 4))
        sets = 0
        while getattr(attrs, f"JOINTS_{sets}", None) is not None:
            joints = self.array(getattr(attrs, f"JOINTS_{sets}"))
            wts = self.array(getattr(attrs, f"WEIGHTS_{sets}"))
            blended += np.einsum("vk,vkab->vab", wts, joint_mats[joints])
            sets += 1
        homo = np.c_[verts, np.ones(len(verts))]
        return np.einsum("vab,vb->va", blended, homo)[:, :3]

    def joint_positions(self, frame: int) -> np.ndarray:
        return self.world_matrices(frame)[self.gltf.skins[0].joints][:, :3, 3]


def quat_to_matrix(q: np.ndarray) -> np.ndarray:
    """(N, 4) unit quaternions (x, y, z, w) -> (N, 3, 3)."""
    q = q / np.linalg.norm(q, axis=-1, keepdims=True)
    x, y, z, w = q[:, 0], q[:, 1], q[:, 2], q[:, 3]
    return np.stack(
        [
            1 - 2 * (y * y + z * z),
            2 * (x * y - z * w),
            2 * (x * z + y * w),
            2 * (x * y + z * w),
            1 - 2 * (x * x + z * z),
            2 * (y * z - x * w),
            2 * (x * z - y * w),
            2 * (y * z + x * w),
            1 - 2 * (x * x + y * y),
        ],
        axis=-1,
    ).reshape(-1, 3, 3)
