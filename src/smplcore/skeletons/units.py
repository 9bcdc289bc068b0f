"""Units and up axis of a skeleton's coordinates, told from its size, and the conversion to metres, Y up.

Lengths are judged by the leg: hip joint → knee → ankle, as the skeleton map names them (an adult's is
0.7-0.95 m, a child's shorter; the open model's neutral body has 0.82 m). A unit is accepted when it makes the
leg 0.6-1.05 m long; the candidates are far enough apart that at most one fits (cm and inch differ 2.54x, the
range spans 1.75x). When none fits (the FAIR capture's units are undocumented: a 21.7-unit leg), the scale that
makes the leg 0.80 m is used and said. The up axis is the direction from the ankles to the hips, in the rest pose
(a BVH skeleton) or over the frames (points), snapped to the nearest axis.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: Metres per unit of the units :func:`parse_units` knows.
UNIT_SCALES: dict[str, float] = {
    "m": 1.0,
    "cm": 0.01,
    "mm": 0.001,
    "in": 0.0254,
    "cmu": 0.0254 / 0.45,  # CMU's ASF skeletons (and cgspeed's MotionBuilder / 3dsMax BVH): 1/0.45 inch
    "ft": 0.3048,
}
UNIT_NAMES = {
    "m": "metres",
    "cm": "centimetres",
    "mm": "millimetres",
    "in": "inches",
    "cmu": "CMU ASF units (0.0254/0.45 m)",
    "ft": "feet",
}
LEG_RANGE = (0.6, 1.05)
"""Plausible hip → knee → ankle length in metres of a BVH skeleton (about 1.25-2.2 m tall)."""
POINTS_UNITS = ("m", "cm", "mm")
"""The units tried for 3D points (keypoints, ``.npy`` joints): a leg of 0.3-1.3 m in one of them (a child too)."""
POINTS_LEG_RANGE = (0.3, 1.3)

LEG_DEFAULT = 0.80
"""The leg length (m) an unknown unit is scaled to."""

#: Rotations taking each up axis to +Y (the rest of the frame turned with it, right-handed).
AXES: dict[str, np.ndarray] = {
    "y": np.eye(3),
    "-y": np.diag([1.0, -1.0, -1.0]),
    "z": np.array([[1.0, 0, 0], [0, 0, 1], [0, -1, 0]]),
    "-z": np.array([[1.0, 0, 0], [0, 0, -1], [0, 1, 0]]),
    "x": np.array([[0.0, -1, 0], [1, 0, 0], [0, 0, 1]]),
    "-x": np.array([[0.0, 1, 0], [-1, 0, 0], [0, 0, 1]]),
}


@dataclass(frozen=True)
class Units:
    """How a skeleton's coordinates become metres with Y up.

    Attributes
    ----------
    scale : metres per unit.
    name : a key of :data:`UNIT_SCALES`, ``"given"`` (a number was given) or ``"estimated"`` (no unit fitted).
    up : the source's up axis (``"y"``, ``"z"``, ``"-y"``, ...).
    leg : the leg length (hip → knee → ankle) in source units, NaN when not measured.
    detected : whether the unit was told from the size (False when given).
    message : what was detected or assumed, in words.
    """

    scale: float
    name: str
    up: str
    leg: float
    detected: bool
    message: str

    @property
    def axes(self) -> np.ndarray:
        """(3, 3) rotation taking the source axes to Y up."""
        return AXES[self.up]


def parse_units(value: str | float) -> tuple[float, str]:
    """Metres per unit and a name, from ``"cm"``, ``"m"``, ``"mm"``, ``"in"``, ``"cmu"``, ``"ft"`` or a number
    (metres per unit, e.g. ``0.0375``)."""
    if isinstance(value, str):
        key = value.strip().lower()
        key = {"inch": "in", "inches": "in", "meters": "m", "metres": "m", "centimetres": "cm"}.get(key, key)
        if key in UNIT_SCALES:
            return UNIT_SCALES[key], key
        try:
            number = float(key)
        except ValueError:
            raise ValueError(
                f"units: expected one of {', '.join(UNIT_SCALES)} or metres per unit (a number), got {value!r}"
            ) from None
    else:
        number = float(value)
    if not (np.isfinite(number) and number > 0):
        raise ValueError(f"units: metres per unit must be a positive number, got {value!r}")
    return number, "given"


def parse_up(value: str) -> str:
    key = str(value).strip().lower().replace("+", "")
    if key not in AXES:
        raise ValueError(f"up: expected one of {', '.join(AXES)}, got {value!r}")
    return key


def snap_up(direction: np.ndarray) -> str | None:
    """The axis (``"y"``, ``"-z"``, ...) nearest to ``direction``, or None when it is more than ~35° from all."""
    norm = float(np.linalg.norm(direction))
    if not np.isfinite(norm) or norm == 0:
        return None
    d = direction / norm
    k = int(np.argmax(np.abs(d)))
    if abs(d[k]) < 0.8:
        return None
    return ("-" if d[k] < 0 else "") + "xyz"[k]


def decide_units(
    leg: float,
    up: str | None,
    units: str | float | None = None,
    up_given: str | None = None,
    what: str = "skeleton",
    points: bool = False,
) -> Units:
    """The :class:`Units` of a skeleton whose leg measures ``leg`` source units and whose up axis looked like
    ``up`` (None: not told), unless ``units`` / ``up_given`` say otherwise.

    ``points=True`` (keypoints, ``.npy`` joints): only metres, centimetres and millimetres are tried, with a leg of
    0.3-1.3 m, and a leg that fits none is an error asking for the units (no scale is guessed for points)."""
    axis = parse_up(up_given) if up_given is not None else (up or "y")
    up_text = (
        f"up axis {axis} (given)"
        if up_given is not None
        else f"up axis {axis}" + (" (assumed: the ankle-to-hip direction was not clear)" if up is None else "")
    )
    if units is not None:
        scale, name = parse_units(units)
        shown = UNIT_NAMES.get(name, f"{scale:g} m per unit")
        leg_m = f"; the leg is {leg * scale:.2f} m" if np.isfinite(leg) else ""
        return Units(scale, name, axis, leg, False, f"units: {shown} (given){leg_m}; {up_text}")
    if not (np.isfinite(leg) and leg > 0):
        raise ValueError(f"units: the {what} has no measurable leg (hip, knee, ankle); give the units")
    names = POINTS_UNITS if points else tuple(UNIT_SCALES)
    low, high = POINTS_LEG_RANGE if points else LEG_RANGE
    told = "the leg, hip to ankle,"
    fits = [(k, UNIT_SCALES[k]) for k in names if low <= leg * UNIT_SCALES[k] <= high]
    if fits:
        name, scale = fits[0]
        text = f"units: {UNIT_NAMES[name]} (detected: the leg, hip to ankle, is {leg:.4g} units = {leg * scale:.2f} m)"
        if name != "m":
            text += f"; converted to metres (x {scale:.6g})"
        return Units(scale, name, axis, leg, True, f"{text}; {up_text}")
    if points:
        raise ValueError(
            f"units: {told.strip(',')} of the {what} is {leg:.4g} units: not a person's in {', '.join(names)} "
            f"({low}-{high} m); give the units (--units: m, cm, mm, in, or metres per unit)"
        )
    scale = LEG_DEFAULT / leg
    text = (
        f"units: unknown (the leg, hip to ankle, is {leg:.4g} units: no unit of {', '.join(UNIT_SCALES)} makes it "
        f"{LEG_RANGE[0]}-{LEG_RANGE[1]} m); scaled to a {LEG_DEFAULT} m leg ({scale:.4g} m per unit); pass the units "
        "to override"
    )
    return Units(scale, "estimated", axis, leg, True, f"{text}; {up_text}")
