"""Fitting: model parameters from observations (vertices, joints), and conversion between models.

``fit_vertices`` starts from a closed-form initialiser (per-part Procrustes rotations, with the joints
the regressor reads off the targets as bone ends, and linear least squares for shape and translation)
and refines with Levenberg–Marquardt on the full model (pose correctives included), batched over bodies
and threads: first on a few hundred points with their exact Gauss–Newton matrix
(:mod:`smplcore.fit.normal_matrix`), then, where the model's own forward shows the whole mesh is not yet
at the precision's floor, on every point with the exact gradient (:mod:`smplcore.fit.dense`,
:mod:`smplcore.fit.gauss_newton`). Works with torch models of :func:`smplcore.create` and the NumPy
:class:`smplcore.BodyModel` alike (the solver runs in NumPy either way; products over points in float32
for float32 models).

``fit_keypoints`` fits 2D keypoints seen by a pinhole :class:`Camera` (OpenCV convention), SMPLify-style:
robust reprojection cost, staged Levenberg–Marquardt, open priors (anatomical joint limits, elbow/knee
bending) and SMPLify's GMM or VPoser v2 when the user has them (:class:`GMMPrior`, :class:`VPoserPrior`);
the focal length known or estimated (``estimate_focal``).

No fit returns what it did not find (:mod:`smplcore.fit.checks`): option values are checked (a NaN weight
is an error, not a switched-off prior), targets more than 10x off the model's size are refused (millimetres),
bodies left further from their targets than half their spread are flagged not converged with a warning, and
a non-finite parameter or error raises :class:`FitError` instead of being returned. Every fit reports
each target point's error and the mask of points used, and which body joints lie outside their anatomical
limits (:func:`assess`, :class:`Plausibility`); a fit of joints or keypoints returning implausible bodies
warns (:class:`ImplausibleFitWarning`).
"""

from smplcore.fit.camera import Camera
from smplcore.fit.checks import FitError
from smplcore.fit.convert import convert, correspondence
from smplcore.fit.joints import fit_joints
from smplcore.fit.keypoints2d import fit_keypoints
from smplcore.fit.plausibility import ImplausibleFitWarning, Plausibility, assess
from smplcore.fit.priors import GMMPrior
from smplcore.fit.result import FitResult
from smplcore.fit.vertices import fit_vertices
from smplcore.fit.visibility import PartialViewWarning
from smplcore.fit.vposer import VPoserPrior

__all__ = [
    "Camera",
    "FitError",
    "FitResult",
    "GMMPrior",
    "ImplausibleFitWarning",
    "PartialViewWarning",
    "Plausibility",
    "VPoserPrior",
    "assess",
    "convert",
    "correspondence",
    "fit_joints",
    "fit_keypoints",
    "fit_vertices",
]
