"""The open model at any age as a :class:`~smplcore.model.Rig`, for fitting age with the betas."""

from __future__ import annotations

import dataclasses

import numpy as np

from smplcore.io import AGE_RANGE, age_offsets
from smplcore.model import Rig

__all__ = ["AgeAxis"]


class AgeAxis:
    """Rigs of the open model of ``rig``'s gender and coefficient count at any age (years in
    :data:`smplcore.io.open_ages.AGE_RANGE`), built the way ``BodyModel(model_type="open", age=years)`` is:
    the adult template plus the age offset, the shape basis scaled by the body's stature over the adult's."""

    def __init__(self, rig: Rig) -> None:
        if rig.model_type != "open":
            raise ValueError(
                f"fit_age: the age axis belongs to the open model (model_type='open'), got a {rig.model_type} model"
            )
        from smplcore import BodyModel

        gender = rig.gender if rig.gender in ("male", "female") else "neutral"
        self.gender = gender
        self.adult = BodyModel(model_type="open", gender=gender, num_betas=rig.num_betas, dtype=np.float64).rig
        if self.adult.num_vertices != rig.num_vertices:
            raise ValueError(
                f"fit_age: expected the open model's {self.adult.num_vertices} vertices, got {rig.num_vertices}"
            )
        self._template = np.asarray(self.adult.template, dtype=np.float64)
        self._shapedirs = np.asarray(self.adult.shapedirs, dtype=np.float64)
        self._stature = float(np.ptp(self._template[:, 1]))
        self.bounds = AGE_RANGE

    def at(self, years: float) -> Rig:
        """The rig at ``years`` of age (template and shape basis aged: what :func:`rest_body` reads; the
        cached template joints stay the adult's)."""
        offset, stature = age_offsets(self.gender, float(years))
        return dataclasses.replace(
            self.adult,
            template=self._template + offset,
            shapedirs=self._shapedirs * (stature / self._stature),
        )
