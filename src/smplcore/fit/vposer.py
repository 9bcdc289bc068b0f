"""VPoser v2 (human_body_prior's ``V02_05``) as a pose prior, in NumPy, from the user's checkpoint.

VPoser is a variational auto-encoder over the 21 body joints' axis-angle rotations (63 values, the body
pose of SMPL+H / SMPL-X; SMPL's first 21 body joints are the same joints). The network, in eval mode:

* encoder: BatchNorm(63) → Linear(63, H) → LeakyReLU(0.01) → BatchNorm(H) → Dropout → Linear(H, H) →
  Linear(H, H) → mean ``Linear(H, L)`` (and a log-variance ``Linear(H, L)``, unused here); V02_05 has
  H = 512 neurons and L = 32 latent values;
* decoder: Linear(L, H) → LeakyReLU → Dropout → Linear(H, H) → LeakyReLU → Linear(H, 126) → per joint,
  six numbers read as the two columns ``a, b`` of a 3 × 2 matrix, orthonormalised (Gram–Schmidt:
  ``r1 = a / |a|``, ``r2`` = the part of ``b`` orthogonal to ``r1``, normalised, ``r3 = r1 × r2``) into
  the rotation with columns ``r1, r2, r3``, then axis-angle.

In eval mode BatchNorm uses its running statistics and Dropout does nothing, so between the one
nonlinearity and the mean the encoder is affine; :class:`VPoserPrior` stores it composed.

**As a prior for fitting** (:func:`smplcore.fit.fit_keypoints`, ``vposer=``): the residuals are the
encoder's mean ``μ(θ)`` (L values) of the body pose θ, cost ``w |μ(θ)|²``, with the encoder's exact
Jacobian. VPoser is trained with a KL term towards a standard normal latent, so poses like its training
data have small ``|μ|``. This keeps the solver's parameters (axis-angle, as every other prior uses), unlike
SMPLify-X, which optimises the latent code z and decodes it. The encoder is only trained on plausible
poses, so far from them ``|μ|`` is an extrapolation: the joint limits stay on beside it.

The checkpoint is read without torch and without running anything in it
(:func:`smplcore.io.load_torch_file`): a PyTorch-Lightning ``.ckpt`` (weights under ``state_dict`` with the
prefix ``vp_model.``), a plain state_dict saved with ``torch.save`` (``.pt``), a ``.npz`` of the same
arrays, or the extracted ``V02_05/`` folder (its newest ``snapshots/*.ckpt``, as human_body_prior picks).
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from smplcore.errors import ModelFileError, ShapeError

NUM_JOINTS = 21
POSE_WIDTH = 3 * NUM_JOINTS
SLOPE = 0.01  # LeakyReLU's default negative slope
BN_EPS = 1e-5  # BatchNorm1d's default eps
PREFIX = "vp_model."
_SUFFIXES = (".ckpt", ".pt", ".pth", ".npz")


def _leaky(x: np.ndarray) -> np.ndarray:
    return np.where(x > 0, x, SLOPE * x)


def _layers(hidden: int, latent: int) -> dict[str, tuple[int, ...]]:
    """The state_dict keys VPoser v2 needs (without ``vp_model.``) and their shapes."""
    shapes: dict[str, tuple[int, ...]] = {}
    for bn, width in (("encoder_net.1", POSE_WIDTH), ("encoder_net.4", hidden)):
        for name in ("weight", "bias", "running_mean", "running_var"):
            shapes[f"{bn}.{name}"] = (width,)
    for key, out, inp in (
        ("encoder_net.2", hidden, POSE_WIDTH), ("encoder_net.6", hidden, hidden), ("encoder_net.7", hidden, hidden),
        ("encoder_net.8.mu", latent, hidden), ("decoder_net.0", hidden, latent), ("decoder_net.3", hidden, hidden),
        ("decoder_net.5", 6 * NUM_JOINTS, hidden),
    ):  # fmt: skip
        shapes[f"{key}.weight"] = (out, inp)
        shapes[f"{key}.bias"] = (out,)
    return shapes


@dataclass(frozen=True)
class VPoserPrior:
    """VPoser v2's encoder mean and decoder, in float64 NumPy.

    Attributes
    ----------
    enc_in, enc_in_bias : (H, 63), (H,) the input BatchNorm folded into the first Linear.
    enc_out, enc_out_bias : (L, H), (L,) BatchNorm(H) → Linear → Linear → mean, composed.
    dec : three (weight (out, in), bias (out,)) pairs: (H, L), (H, H), (126, H).
    source : where it came from.
    """

    enc_in: np.ndarray
    enc_in_bias: np.ndarray
    enc_out: np.ndarray
    enc_out_bias: np.ndarray
    dec: tuple[tuple[np.ndarray, np.ndarray], ...]
    source: str = "<arrays>"

    @property
    def latent_dim(self) -> int:
        return int(self.enc_out.shape[0])

    @classmethod
    def from_state_dict(cls, state: Mapping[str, Any], source: str = "<state_dict>") -> VPoserPrior:
        """A prior from VPoser v2's state_dict (keys with or without ``vp_model.``, arrays or tensors).

        Raises
        ------
        ModelFileError
            naming ``source`` and the key: a missing key, a wrong shape, non-finite values.
        """
        prefixed = any(str(k).startswith(PREFIX) for k in state)
        prefix = PREFIX if prefixed else ""
        first = prefix + "encoder_net.2.weight"
        if first not in state:
            v1 = any("bodyprior_enc" in str(k) for k in state)
            raise ModelFileError(
                source,
                "this is VPoser v1 (vposer_v1_0), which is not supported; use VPoser v2 (V02_05)"
                if v1
                else "missing; expected VPoser v2's state_dict (encoder_net.*, decoder_net.*)",
                key=first,
            )
        hidden = int(np.shape(state[first])[0])
        mu = prefix + "encoder_net.8.mu.weight"
        latent = int(np.shape(state[mu])[0]) if mu in state else 32
        arrays: dict[str, np.ndarray] = {}
        for key, shape in _layers(hidden, latent).items():
            full = prefix + key
            if full not in state:
                raise ModelFileError(source, "missing from the VPoser v2 state_dict", key=full)
            value = state[full]
            value = value.detach().cpu().numpy() if hasattr(value, "detach") else value
            try:
                array = np.asarray(value, dtype=np.float64)
            except (TypeError, ValueError):
                raise ModelFileError(
                    source, f"expected a numeric array, found {type(value).__name__}", key=full
                ) from None
            if array.shape != shape:
                raise ModelFileError(source, f"expected shape {shape}, found {array.shape}", key=full)
            if not np.all(np.isfinite(array)):
                raise ModelFileError(source, "holds NaN or infinite values", key=full)
            arrays[key] = array
        for norm in ("encoder_net.1", "encoder_net.4"):
            if np.any(arrays[f"{norm}.running_var"] < 0):
                raise ModelFileError(source, "negative running variance", key=prefix + norm + ".running_var")

        def bn(name: str) -> tuple[np.ndarray, np.ndarray]:  # y = x * scale + shift
            scale = arrays[f"{name}.weight"] / np.sqrt(arrays[f"{name}.running_var"] + BN_EPS)
            return scale, arrays[f"{name}.bias"] - arrays[f"{name}.running_mean"] * scale

        s1, t1 = bn("encoder_net.1")
        w2, b2 = arrays["encoder_net.2.weight"], arrays["encoder_net.2.bias"]
        s4, t4 = bn("encoder_net.4")
        tail_w, tail_b = np.diag(s4), t4
        for key in ("encoder_net.6", "encoder_net.7", "encoder_net.8.mu"):
            w, b = arrays[f"{key}.weight"], arrays[f"{key}.bias"]
            tail_w, tail_b = w @ tail_w, w @ tail_b + b
        dec = tuple((arrays[f"decoder_net.{i}.weight"], arrays[f"decoder_net.{i}.bias"]) for i in (0, 3, 5))
        return cls(w2 * s1, w2 @ t1 + b2, tail_w, tail_b, dec, str(source))

    @classmethod
    def load(cls, path: str | os.PathLike[str]) -> VPoserPrior:
        """Read VPoser v2 from a Lightning ``.ckpt``, a state_dict ``.pt``/``.npz``, or the ``V02_05/`` folder
        (its newest ``snapshots/*.ckpt``). Nothing in the file is run; torch is not needed."""
        from smplcore.io import read_arrays, read_checkpoint

        file = _checkpoint_file(Path(path))
        what = "a VPoser v2 checkpoint (.ckpt, .pt or .npz)"
        content = read_arrays(file, what) if file.suffix.lower() == ".npz" else read_checkpoint(file, what)
        content = dict(content) if isinstance(content, Mapping) else content
        state = content.get("state_dict", content) if isinstance(content, dict) else None
        if not isinstance(state, dict) or not all(isinstance(k, str) for k in state):
            raise ModelFileError(
                file, "expected a PyTorch-Lightning checkpoint with a 'state_dict', or a state_dict of VPoser v2"
            )
        try:
            return cls.from_state_dict(state, str(file))
        except ModelFileError:
            raise
        except Exception as exc:  # noqa: BLE001 - ragged lists, odd values: a file error
            raise ModelFileError(file, f"unusable VPoser state_dict ({type(exc).__name__}: {exc})") from None

    # -- forward -------------------------------------------------------------------------------------
    def _pose(self, pose: Any) -> np.ndarray:
        theta = np.asarray(pose.detach().cpu().numpy() if hasattr(pose, "detach") else pose, np.float64)
        if theta.ndim == 1:
            theta = theta[None]
        theta = theta.reshape(len(theta), -1)
        if theta.shape[1] != POSE_WIDTH:
            raise ShapeError(f"pose: expected (B, {POSE_WIDTH}) axis-angle of the 21 body joints, got {np.shape(pose)}")
        return theta

    def encode(self, pose: Any) -> np.ndarray:
        """(B, L) means of the latent code of (B, 63) body poses (axis-angle of the 21 body joints)."""
        theta = self._pose(pose)
        return _leaky(theta @ self.enc_in.T + self.enc_in_bias) @ self.enc_out.T + self.enc_out_bias

    def residuals(self, pose: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The encoder mean (B, L) of (B, 63) poses and its Jacobian (B, L, 63)."""
        theta = self._pose(pose)
        pre = theta @ self.enc_in.T + self.enc_in_bias  # (B, H)
        mean = _leaky(pre) @ self.enc_out.T + self.enc_out_bias
        slope = np.where(pre > 0, 1.0, SLOPE)  # (B, H)
        jac = (self.enc_out[None] * slope[:, None, :]) @ self.enc_in
        return mean, jac

    def decode_rotations(self, z: Any) -> np.ndarray:
        """(B, 21, 3, 3) rotation matrices of (B, L) latent codes."""
        h = np.asarray(z.detach().cpu().numpy() if hasattr(z, "detach") else z, np.float64)
        if h.ndim != 2 or h.shape[1] != self.latent_dim:
            raise ShapeError(f"z: expected (B, {self.latent_dim}) latent codes, got {np.shape(z)}")
        (w0, b0), (w3, b3), (w5, b5) = self.dec
        h = _leaky(h @ w0.T + b0)
        h = _leaky(h @ w3.T + b3)
        six = (h @ w5.T + b5).reshape(len(h), NUM_JOINTS, 3, 2)
        a, b = six[..., 0], six[..., 1]
        r1 = a / np.maximum(np.linalg.norm(a, axis=-1, keepdims=True), 1e-12)
        r2 = b - np.sum(r1 * b, axis=-1, keepdims=True) * r1
        r2 = r2 / np.maximum(np.linalg.norm(r2, axis=-1, keepdims=True), 1e-12)
        return np.stack([r1, r2, np.cross(r1, r2)], axis=-1)

    def decode(self, z: Any) -> np.ndarray:
        """(B, 63) axis-angle body poses of (B, L) latent codes."""
        from scipy.spatial.transform import Rotation

        rot = self.decode_rotations(z)
        return Rotation.from_matrix(rot.reshape(-1, 3, 3)).as_rotvec().reshape(len(rot), POSE_WIDTH)


def _checkpoint_file(path: Path) -> Path:
    """The checkpoint file of ``path``: itself, or a folder's (``snapshots/``'s) newest checkpoint."""
    if path.is_file() or (path.is_symlink() and not path.is_dir()):
        return path  # (a dangling or looping link: the reader says which)
    if not path.is_dir():
        if os.path.lexists(path):  # a FIFO, device or socket: refused by the reader without opening it
            return path
        raise ModelFileError(path, "no such file or folder (VPoser v2 comes as V02_05.zip from the SMPL-X site)")
    for folder in (path / "snapshots", path):
        found = (
            [p for p in folder.glob("*") if p.suffix.lower() in _SUFFIXES and p.is_file()] if folder.is_dir() else []
        )
        if found:
            return max(found, key=lambda p: (p.stat().st_mtime, p.name))
    raise ModelFileError(path, "no VPoser checkpoint (snapshots/*.ckpt, *.pt or *.npz) in this folder")
