"""Pose priors for fitting: anatomical joint limits, the elbow/knee bending prior, and SMPLify's GMM.

All priors act on the local axis-angle rotations of the body joints (``body_pose``) and are written as
least-squares residuals ``r(θ)`` with their Jacobians, so the Gauss–Newton solvers can use them.

**Joint limits (open, needs no registration).** A soft bound per axis-angle component of each body
joint: zero inside ``[lo, hi]``, the distance outside (squared in the cost). SMPL's joint frames are
the world axes of the rest pose (x: the body's left, y: up, z: forward), so for moderate rotations the
components are close to the anatomical movements listed in the table. Ranges are given for the left
side; the right side mirrors them (x kept, y and z negated). Sources: the average ranges of motion of
the American Academy of Orthopaedic Surgeons (AAOS, *Joint Motion: Method of Measuring and Recording*,
1965; tabulated in Greene & Heckman, *The Clinical Measurement of Joint Motion*, AAOS 1994) and the
neutral-zero method of Ryf & Weymann (*Range of Motion — AO Neutral-0 Method*, Thieme 1999). Where a
range is split over several SMPL joints (the spine's three, the neck and head) it is divided evenly.
Ranges marked *smplcore* in :data:`JOINT_LIMITS` are not published values but our own bounds for
movements the sources do not list separately (knee axial rotation, the collar bones, toe side bend).

**Bending prior.** SMPLify's observation that elbows and knees bend one way only: a hinge on the
flexion component (left elbow −y, right elbow +y, knees +x) penalising the wrong sign.

**GMM.** SMPLify's ``gmm_08.pkl`` (8 Gaussians over the 69 body-pose values of SMPL), the user's file,
read through smplcore's allow-list unpickler. The cost of the best component at the current pose
(``½ (θ−μ)ᵀ Σ⁻¹ (θ−μ) − log w``, the max-mixture approximation), as residuals ``Lᵀ(θ−μ)``. For models
with 21 body joints (SMPL+H, SMPL-X) the first 63 values are used (the Gaussians' marginals).
:meth:`GMMPrior.open` is smplcore's own mixture of the same form, learned from open motion capture (CMU mocap,
FAIR AnimatedDrawings) by ``tools/train_pose_prior.py``: it needs no registration or download.
"""

from __future__ import annotations

import functools
import os
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from smplcore.errors import ModelFileError

# name: ((x lo, x hi), (y lo, y hi), (z lo, z hi)) in degrees, left side / midline; source note
JOINT_LIMITS: dict[str, tuple[tuple[tuple[float, float], ...], str]] = {
    "left_hip": (
        ((-120, 30), (-45, 45), (-30, 45)),
        "AAOS: flexion 120, extension 30, rotation 45/45, adduction 30, abduction 45",
    ),
    "left_knee": (
        ((0, 135), (-20, 20), (-10, 10)),
        "AAOS: flexion 135, extension 0; rotation and varus/valgus: smplcore",
    ),
    "left_ankle": (
        ((-20, 50), (-30, 30), (-35, 15)),
        "AAOS: dorsiflexion 20, plantar flexion 50, inversion 35, eversion 15; y (ab/adduction): smplcore",
    ),
    "left_foot": (((-70, 45), (-10, 10), (-10, 10)), "AAOS great toe MTP: extension 70, flexion 45; y, z: smplcore"),
    "spine1": (
        ((-25 / 3, 80 / 3), (-15, 15), (-35 / 3, 35 / 3)),
        "AAOS thoracolumbar: flexion 80, extension 25, rotation 45, lateral bending 35; a third per spine joint",
    ),
    "spine2": (((-25 / 3, 80 / 3), (-15, 15), (-35 / 3, 35 / 3)), "as spine1"),
    "spine3": (((-25 / 3, 80 / 3), (-15, 15), (-35 / 3, 35 / 3)), "as spine1"),
    "neck": (
        ((-22.5, 22.5), (-30, 30), (-22.5, 22.5)),
        "AAOS cervical: flexion 45, extension 45, rotation 60, lateral bending 45; half per joint (neck, head)",
    ),
    "head": (((-22.5, 22.5), (-30, 30), (-22.5, 22.5)), "as neck"),
    "left_collar": (((-15, 15), (-30, 30), (-10, 45)), "smplcore (shoulder girdle elevation, protraction)"),
    "left_shoulder": (
        ((-90, 70), (-135, 45), (-135, 90)),
        "AAOS: internal rotation 70, external 90 "
        "(x), horizontal adduction 135, abduction 45 (y), abduction 180 = T-pose + 90, "
        "adduction 45 past the side (z)",
    ),
    "left_elbow": (
        ((-80, 80), (-150, 5), (-15, 15)),
        "AAOS: flexion 150, extension 0 (5 allowed), pronation 80, supination 80 (x); carrying angle z: smplcore",
    ),
    "left_wrist": (
        ((-40, 40), (-20, 30), (-80, 70)),
        "AAOS: flexion 80, extension 70 (z), radial 20, "
        "ulnar deviation 30 (y); twist x: part of forearm rotation, smplcore",
    ),
    "left_hand": (((-30, 30), (-30, 30), (-90, 45)), "AAOS finger MCP: flexion 90, extension 45 (z); x, y: smplcore"),
}

#: (joint name, axis, sign): ``sign · θ_axis > 0`` is bending the wrong way.
BENDING = (("left_elbow", 1, 1.0), ("right_elbow", 1, -1.0), ("left_knee", 0, -1.0), ("right_knee", 0, -1.0))


def joint_limits(joint_names: list[str] | tuple[str, ...]) -> tuple[np.ndarray, np.ndarray]:
    """Lower and upper bounds (radians), each (J, 3), for joints named ``joint_names`` (±π where no
    limit is known, e.g. the pelvis)."""
    lo = np.full((len(joint_names), 3), -np.pi)
    hi = np.full((len(joint_names), 3), np.pi)
    for j, name in enumerate(joint_names):
        key, mirror = name, False
        if name.startswith("right_"):
            key, mirror = "left_" + name[len("right_") :], True
        if key not in JOINT_LIMITS:
            continue
        bounds = np.radians(np.asarray(JOINT_LIMITS[key][0], np.float64))
        if mirror:  # reflect x → −x: axis-angle (x, y, z) → (x, −y, −z)
            bounds[1:] = -bounds[1:, ::-1]
        lo[j], hi[j] = bounds[:, 0], bounds[:, 1]
    return lo, hi


def limit_residuals(theta: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Residuals (B, D) of the soft bounds on (B, D) values and their diagonal Jacobian (B, D)."""
    below, above = theta < lo, theta > hi
    res = np.where(below, theta - lo, np.where(above, theta - hi, 0.0))
    return res, (below | above).astype(np.float64)


def bending_residuals(theta: np.ndarray, index: np.ndarray, sign: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Hinge residuals (B, m) ``max(0, sign θ_index)`` and their Jacobian values (B, m) on ``θ_index``."""
    value = theta[:, index] * sign
    active = value > 0
    return np.where(active, value, 0.0), np.where(active, sign, 0.0)


@dataclass(frozen=True)
class GMMPrior:
    """A Gaussian mixture over body-pose values (SMPLify's ``gmm_08.pkl``).

    Attributes
    ----------
    means : (C, D) component means.
    chol : (C, D, D) ``L`` with ``L Lᵀ = Σ⁻¹`` (precision Cholesky factors).
    penalty : (C,) ``−log w + ½ log det Σ`` (the constant of each component's negative log-likelihood).
    source : where it came from.
    """

    means: np.ndarray
    chol: np.ndarray
    penalty: np.ndarray
    source: str = "<arrays>"

    @classmethod
    def from_arrays(cls, means: np.ndarray, covars: np.ndarray, weights: np.ndarray, source: str = "<arrays>"):
        """A prior from (C, D) means, (C, D, D) covariances and (C,) weights."""
        try:
            means = np.asarray(means, np.float64)
            covars = np.asarray(covars, np.float64)
            weights = np.asarray(weights, np.float64).reshape(-1)
        except (TypeError, ValueError) as exc:
            raise ModelFileError(source, f"means, covars, weights: expected arrays of numbers ({exc})") from exc
        c = len(weights)
        if c == 0 or means.ndim != 2 or means.shape[0] != c or covars.shape != (c, means.shape[1], means.shape[1]):
            raise ModelFileError(
                source,
                f"expected means (C, D), covars (C, D, D), weights (C,); got {means.shape}, {covars.shape}, "
                f"{weights.shape}",
            )
        if not (np.all(np.isfinite(means)) and np.all(np.isfinite(covars)) and np.all(weights > 0)):
            raise ModelFileError(source, "the mixture holds non-finite values or non-positive weights")
        try:
            chol = np.linalg.cholesky(np.linalg.inv(covars))
        except np.linalg.LinAlgError as exc:
            raise ModelFileError(source, "a covariance is not positive definite", key="covars") from exc
        _, logdet = np.linalg.slogdet(covars)
        return cls(means, chol, -np.log(weights / weights.sum()) + 0.5 * logdet, source)

    @classmethod
    def load(cls, path: str | os.PathLike[str]) -> GMMPrior:
        """Read ``gmm_08.pkl`` (a pickled dict with ``means``, ``covars``, ``weights``) through smplcore's
        allow-list unpickler (nothing in the file is run)."""
        from smplcore.io import numeric_array, read_arrays

        path = Path(path)
        if not path.exists() and not path.is_symlink():
            raise ModelFileError(path, "no such file (SMPLify's gmm_08.pkl comes with SMPLify's download)")
        data = read_arrays(path, "a GMM pose prior (SMPLify's gmm_08.pkl)")
        keys = ("means", "covars", "weights")
        missing = [k for k in keys if not isinstance(data, Mapping) or k not in data]
        if missing:
            raise ModelFileError(path, f"expected a dict with means, covars and weights; missing {missing}")
        means, covars, weights = (numeric_array(path, data[k], k, kinds="biuf") for k in keys)
        return cls.from_arrays(means, covars, weights, str(path))

    @classmethod
    def open(cls) -> GMMPrior:
        """smplcore's open pose prior (``smplcore/data/pose_prior_open.npz``): a Gaussian mixture over the 69
        body-pose values of SMPL's 23 body joints (``.marginal(63)`` for the 21 of SMPL+H / SMPL-X), learned from
        CMU and FAIR motion capture retargeted to the open model; the file's ``provenance`` states the data, its
        licence, the held-out subjects and the command that rebuilds it."""
        return _open_prior()

    @property
    def dim(self) -> int:
        return int(self.means.shape[1])

    def marginal(self, dim: int) -> GMMPrior:
        """The mixture of the first ``dim`` values (exact marginals of each Gaussian)."""
        if isinstance(dim, bool) or not isinstance(dim, (int, np.integer)) or dim < 1:
            raise ValueError(f"dim: expected a positive number of pose values, got {dim!r}")
        if dim == self.dim:
            return self
        if dim > self.dim:
            raise ValueError(f"gmm: the mixture covers {self.dim} pose values, the model's body pose has {dim}")
        precision = self.chol @ np.swapaxes(self.chol, 1, 2)
        covars = np.linalg.inv(precision)[:, :dim, :dim]
        weights = np.exp(-(self.penalty - 0.5 * np.linalg.slogdet(np.linalg.inv(precision))[1]))
        return GMMPrior.from_arrays(self.means[:, :dim], covars, weights, self.source)

    def residuals(self, theta: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The best component of each (B, D) pose, its residuals (B, D) ``Lᵀ(θ − μ)`` and Jacobian
        (B, D, D) ``Lᵀ``; the cost is ``½|r|² + penalty``."""
        diff = theta[:, None, :] - self.means[None]  # (B, C, D)
        res = (diff[:, :, None, :] @ self.chol[None])[:, :, 0]  # (B, C, D): Lᵀ(θ − μ) per component
        cost = 0.5 * np.sum(res * res, axis=-1) + self.penalty
        best = np.argmin(cost, axis=1)
        rows = np.arange(len(theta))
        return best, res[rows, best], np.swapaxes(self.chol[best], 1, 2)


@functools.cache
def _open_prior() -> GMMPrior:
    """The shipped open prior, read once per process (every fit that uses it shares it; do not modify it)."""
    path = Path(__file__).resolve().parents[1] / "data" / "pose_prior_open.npz"
    if not path.exists():
        raise ModelFileError(path, "the open pose prior is missing from the installation (reinstall smplcore)")
    with np.load(path, allow_pickle=False) as data:
        return GMMPrior.from_arrays(data["means"], data["covars"], data["weights"], str(path))
