"""Bodies by measurement: anthropometry of any body of the family, and shapes from measurements.

>>> from smplcore import BodyModel
>>> from smplcore import measure
>>> model = BodyModel(model_type="open")
>>> round(measure.measure(model, names=["stature"])["stature"], 2)
1.69

See docs/measure.md for the definitions (ISO 8559-1, ISO 7250-1, ANSUR II), the picture of the landmarks
and cutting planes, and :func:`fit_shape`.
"""

from smplcore.io import age_for_stature
from smplcore.measure.api import measure, measure_mesh
from smplcore.measure.definitions import DEFAULT_DENSITY, MEASUREMENTS, UNITS
from smplcore.measure.fit import TOLERANCES, ShapeFit, fit_shape

__all__ = [
    "measure",
    "measure_mesh",
    "fit_shape",
    "ShapeFit",
    "MEASUREMENTS",
    "UNITS",
    "DEFAULT_DENSITY",
    "TOLERANCES",
    "age_for_stature",
]
