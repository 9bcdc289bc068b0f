"""Edge cases of the fitting solver that the type checker pointed at."""

from __future__ import annotations

import numpy as np

import smplcore
from smplcore.fit.body import FitBody
from smplcore.fit.result import params_to_state
from smplcore.fit.solver import Objective, levenberg_marquardt, residual_cost
from smplcore.fit.vertices import coefficient_masks


def test_zero_iterations_return_the_cost_of_the_start():
    model = smplcore.BodyModel(model_type="open", dtype=np.float64)
    body = FitBody.from_model(model)
    ids = np.arange(0, body.num_vertices, 97)
    targets = model(betas=np.ones((2, 10)) * 0.5).vertices[:, ids]
    free, shared = coefficient_masks(body, True, False, False)
    obj = Objective(body.points(ids), targets, np.ones((2, len(ids))), free, shared)
    start = params_to_state(body, {}, 2)
    state, cost, converged, iterations = levenberg_marquardt(body, obj, start, max_iter=0)
    assert iterations == 0 and not converged.any()
    np.testing.assert_array_equal(cost, residual_cost(body, obj, start))
    assert cost.shape == (2,) and np.all(cost > 0)
