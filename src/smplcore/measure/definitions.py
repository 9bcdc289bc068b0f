"""Body measurements on a mesh, each defined after a standard (ISO 8559-1:2017, ISO 7250-1:2017, ANSUR II).

The landmarks are found geometrically from the body's joints (the SMPL-layout joints every model of the
family has) and the surface, so the same definitions hold for SMPL, SMPL+H, SMPL-X, the open model and any
mesh given with those joints; no per-topology vertex list is needed (none of the licensed topologies' vertex
ids could be checked here, and the open model has its own mesh). The body is taken upright along +Y (the
family's rest pose, a T-pose); "horizontal" means perpendicular to +Y. Unilateral measurements are taken on
the body's right side, as ISO 7250-1 and ANSUR II do. Lengths are in metres, mass in kg, BMI in kg/m².

Every measurement comes with its first-order dependence on the vertices (:class:`~.geometry.Linear`),
which the shape fit chains through the shape basis.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from smplcore.measure.geometry import Linear, Loop, Topology, hull_girth, pick_loop, section, topology, volume

__all__ = ["MEASUREMENTS", "UNITS", "DEFAULT_DENSITY", "Body", "measure_body"]

#: kg/m³, whole-body density that turns the closed mesh volume into mass. The same value
#: ``tools/build_open_model.py`` used to give the open model its population's BMI, so the open model's
#: measured mass agrees with its own calibration. Whole-body densities measured with air in the lungs lie
#: around 985-1070 kg/m³ depending on body fat (two-compartment model of W. E. Siri, "Body composition from
#: fluid spaces and density", 1961: fat 900 kg/m³, fat-free mass 1100 kg/m³); pass ``density=`` to change it.
DEFAULT_DENSITY = 1010.0

UP = np.array([0.0, 1.0, 0.0])
SAGITTAL = np.array([1.0, 0.0, 0.0])  # normal of the mid-sagittal plane (SMPL's left is +X)

#: The measurements, in the order tables print them, with their units.
UNITS: dict[str, str] = {
    "stature": "m",
    "mass": "kg",
    "bmi": "kg/m^2",
    "volume": "m^3",
    "chest": "m",
    "under_bust": "m",
    "waist": "m",
    "hip": "m",
    "thigh": "m",
    "calf": "m",
    "upper_arm": "m",
    "neck": "m",
    "inseam": "m",
    "shoulder_breadth": "m",
    "arm_length": "m",
    "sitting_height": "m",
}
MEASUREMENTS: tuple[str, ...] = tuple(UNITS)

_NEEDED_JOINTS = (
    "pelvis",
    "right_hip",
    "right_knee",
    "right_ankle",
    "neck",
    "head",
    "left_shoulder",
    "right_shoulder",
    "left_elbow",
    "right_elbow",
    "right_wrist",
)


@dataclass
class Body:
    """One body to measure: ``vertices`` (V, 3), ``faces`` (F, 3), ``joints`` name -> (3,), and optionally
    the joint regressor (J, V) with the joints' names, for the joints' part of the gradients."""

    vertices: np.ndarray
    faces: np.ndarray
    joints: dict[str, np.ndarray]
    regressor: dict[str, tuple[np.ndarray, np.ndarray]] = field(default_factory=dict)
    density: float = DEFAULT_DENSITY
    topo: Topology = field(init=False)
    landmarks: dict[str, np.ndarray] = field(default_factory=dict)
    planes: dict[str, tuple[np.ndarray, np.ndarray]] = field(default_factory=dict)
    _cache: dict[str, Linear] = field(default_factory=dict)

    def __post_init__(self) -> None:
        self.vertices = np.asarray(self.vertices, dtype=np.float64)
        self.topo = topology(self.faces)
        missing = [n for n in _NEEDED_JOINTS if n not in self.joints]
        if missing:
            raise ValueError(f"joints: the SMPL-layout joints {missing} are needed to place the landmarks")

    # -- helpers ---------------------------------------------------------------------------------
    def j(self, name: str) -> np.ndarray:
        return np.asarray(self.joints[name], dtype=np.float64)

    def joint_linear(self, name: str, direction: np.ndarray) -> Linear:
        """``joint · direction`` with its dependence on the vertices through the regressor."""
        value = float(self.j(name) @ direction)
        if name not in self.regressor:
            return Linear.constant(value)
        cols, coef = self.regressor[name]
        return Linear(value, cols, coef[:, None] * np.asarray(direction, dtype=np.float64)[None, :])

    def point_linear(self, loop: Loop, index: int, direction: np.ndarray) -> Linear:
        """Coordinate along ``direction`` of a section point, held at its edge and interpolation weight."""
        e = self.topo.edges[loop.edge[index]]
        t = float(loop.t[index])
        d = np.asarray(direction, dtype=np.float64)
        return Linear(float(loop.points[index] @ d), e.copy(), np.stack([(1.0 - t) * d, t * d]))

    def girth(self, name: str, point: np.ndarray, normal: np.ndarray, centre: np.ndarray | None = None) -> Linear:
        loops = section(self.vertices, self.topo, point, normal)
        loop = pick_loop(loops, point if centre is None else centre, normal)
        if loop is None:
            raise ValueError(f"{name}: the cutting plane through {np.round(point, 3)} misses the mesh")
        self.planes[name] = (np.asarray(point, dtype=np.float64), np.asarray(normal, dtype=np.float64))
        return hull_girth(loop, self.topo, normal)

    def extreme_girth(self, name: str, lo: float, hi: float, where: Callable[[float], tuple], largest: bool) -> Linear:
        """The largest (or smallest) girth over planes ``where(s)`` for s in [lo, hi]: 9 samples then 5 more
        around the best one."""
        best: tuple[float, Linear, tuple] | None = None
        for grid in (np.linspace(lo, hi, 9), None):
            if grid is None:
                assert best is not None
                step = (hi - lo) / 8.0
                grid = np.linspace(max(lo, best[0] - step), min(hi, best[0] + step), 5)
            for s in grid:
                plane = where(float(s))
                g = self.girth(name, *plane)
                if best is None or (g.value > best[1].value if largest else g.value < best[1].value):
                    best = (float(s), g, plane)
        assert best is not None
        self.girth(name, *best[2])  # record the chosen plane
        return best[1]

    def cached(self, name: str, fn: Callable[[], Linear]) -> Linear:
        if name not in self._cache:
            self._cache[name] = fn()
        return self._cache[name]

    # -- landmarks -------------------------------------------------------------------------------
    @property
    def floor(self) -> Linear:
        """Floor level: the lowest vertex (the soles in the standing rest pose)."""

        def f() -> Linear:
            i = int(np.argmin(self.vertices @ UP))
            self.landmarks["sole"] = self.vertices[i]
            return Linear(float(self.vertices[i] @ UP), np.array([i]), UP[None, :].copy())

        return self.cached("floor", f)

    @property
    def vertex_top(self) -> Linear:
        """Vertex (ISO 7250-1 stature landmark): the highest point of the head."""

        def f() -> Linear:
            i = int(np.argmax(self.vertices @ UP))
            self.landmarks["vertex"] = self.vertices[i]
            return Linear(float(self.vertices[i] @ UP), np.array([i]), UP[None, :].copy())

        return self.cached("vertex_top", f)

    @property
    def crotch(self) -> Linear:
        """Crotch point: the lowest point of the trunk's contour in the mid-sagittal plane (through the
        pelvis joint), i.e. where the legs part."""

        def f() -> Linear:
            pelvis = self.j("pelvis")
            loops = section(self.vertices, self.topo, pelvis, SAGITTAL)
            loop = pick_loop(loops, pelvis, SAGITTAL)
            if loop is None:
                raise ValueError("crotch: the mid-sagittal plane misses the mesh")
            below = np.flatnonzero(loop.points @ UP < pelvis @ UP)
            i = int(below[np.argmin(loop.points[below] @ UP)]) if len(below) else int(np.argmin(loop.points @ UP))
            self.landmarks["crotch"] = loop.points[i]
            self.planes["mid_sagittal"] = (pelvis, SAGITTAL)
            return self.point_linear(loop, i, UP)

        return self.cached("crotch", f)

    @property
    def armpit(self) -> float:
        """Axilla level: the lowest horizontal plane that cuts the right arm (found by bisection between
        the pelvis and the shoulder joint), i.e. where the arm leaves the trunk."""
        if "armpit" not in self._cache:
            pelvis, sh, el = self.j("pelvis"), self.j("right_shoulder"), self.j("right_elbow")
            reach = abs(sh[0] - pelvis[0]) + 0.4 * abs(el[0] - sh[0])
            lo, hi = float(pelvis @ UP), float(sh @ UP)
            for _ in range(11):
                mid = 0.5 * (lo + hi)
                loops = section(self.vertices, self.topo, np.array([pelvis[0], mid, pelvis[2]]), UP)
                arm = any(np.any(pelvis[0] - lp.points[:, 0] > reach) for lp in loops)
                lo, hi = (lo, mid) if arm else (mid, hi)
            self._cache["armpit"] = Linear.constant(hi)
            self.landmarks["axilla"] = np.array([sh[0], hi, sh[2]])
        return self._cache["armpit"].value

    def set_armpit(self, level: float) -> None:
        """Use ``level`` as the axilla level (e.g. the rest pose's, for a body posed with its arms down)."""
        self._cache["armpit"] = Linear.constant(float(level))
        sh = self.j("right_shoulder")
        self.landmarks["axilla"] = np.array([sh[0], level, sh[2]])

    def acromion(self, side: str) -> tuple[Loop, int]:
        """Acromion (ISO 7250-1): the top of the shoulder, taken as the highest point of the section
        perpendicular to the upper arm through the shoulder joint."""
        sh = self.j(f"{side}_shoulder")
        axis = self.j(f"{side}_elbow") - sh
        axis = axis / np.linalg.norm(axis)
        loops = section(self.vertices, self.topo, sh, axis)
        loop = pick_loop(loops, sh, axis)
        if loop is None:
            raise ValueError(f"shoulder_breadth: the plane through the {side} shoulder joint misses the mesh")
        i = int(np.argmax(loop.points @ UP))
        self.landmarks[f"{side}_acromion"] = loop.points[i]
        return loop, i

    def trunk_plane(self, y: float) -> tuple[np.ndarray, np.ndarray]:
        p = self.j("pelvis")
        return np.array([p[0], y, p[2]]), UP

    def limb_plane(self, a: str, b: str, s: float, start: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        pa = self.j(a) if start is None else start
        pb = self.j(b)
        axis = pb - pa
        return pa + s * axis, axis / np.linalg.norm(axis)


# -- the measurements ------------------------------------------------------------------------------


def _stature(b: Body) -> Linear:
    """Stature (ISO 7250-1 4.1.2, ANSUR II STATURE): vertical distance from the floor (the soles) to the
    highest point of the head (vertex)."""
    return b.vertex_top - b.floor


def _volume(b: Body) -> Linear:
    """Body volume: the closed mesh's volume (holes fan-closed, see :func:`.geometry.volume`)."""
    return b.cached("volume", lambda: volume(b.vertices, b.topo))


def _mass(b: Body) -> Linear:
    """Mass: volume × density (:data:`DEFAULT_DENSITY` unless given)."""
    return _volume(b).scaled(b.density)


def _bmi(b: Body) -> Linear:
    """Body-mass index: mass / stature² (WHO)."""
    m, h = _mass(b), _stature(b)
    value = m.value / h.value**2
    grad = m.scaled(1.0 / h.value**2) + h.scaled(-2.0 * m.value / h.value**3)
    return Linear(value, grad.rows, grad.weights)


def _chest(b: Body) -> Linear:
    """Chest / bust girth (ISO 8559-1 5.3.4 bust girth, ANSUR II CHEST CIRCUMFERENCE): the largest
    horizontal girth of the trunk, tape over the bust points, between the axilla and 30 % of the way down
    to the pelvis (the bust level); arms excluded (T-pose)."""
    top, pel = b.armpit, float(b.j("pelvis") @ UP)
    d = top - pel
    return b.extreme_girth("chest", top - 0.30 * d, top - 0.06 * d, lambda y: b.trunk_plane(y), True)


def _under_bust(b: Body) -> Linear:
    """Under-bust girth (ISO 8559-1 5.3.6): horizontal girth of the trunk just below the breasts, taken as
    the smallest girth from the bust level down 20 % of the bust-to-pelvis height."""
    _chest(b)
    bust = float(b.planes["chest"][0] @ UP)
    d = bust - float(b.j("pelvis") @ UP)
    return b.extreme_girth("under_bust", bust - 0.20 * d, bust - 0.02 * d, lambda y: b.trunk_plane(y), False)


def _waist(b: Body) -> Linear:
    """Waist girth (ISO 8559-1 5.3.10): girth of the natural waistline between the top of the hip bones
    and the lower ribs, the smallest horizontal trunk girth from 10 % to 70 % of the pelvis-to-axilla
    height."""
    pel = float(b.j("pelvis") @ UP)
    d = b.armpit - pel
    return b.extreme_girth("waist", pel + 0.10 * d, pel + 0.70 * d, lambda y: b.trunk_plane(y), False)


def _hip(b: Body) -> Linear:
    """Hip girth (ISO 8559-1 5.3.13, ANSUR II BUTTOCK CIRCUMFERENCE): horizontal girth at the level of the
    greatest protrusion of the buttocks, the largest trunk girth between 1 cm above the crotch and 10 % of
    the pelvis-to-axilla height above the pelvis joint."""
    lo = b.crotch.value + 0.01
    pel = float(b.j("pelvis") @ UP)
    hi = pel + 0.10 * (b.armpit - pel)
    return b.extreme_girth("hip", lo, max(hi, lo + 0.01), lambda y: b.trunk_plane(y), True)


def _thigh(b: Body) -> Linear:
    """Thigh girth (ISO 8559-1 5.3.20, ANSUR II THIGH CIRCUMFERENCE): right thigh, just below the gluteal
    fold: the plane perpendicular to the femur (hip to knee joint) 3 % of the leg length below the
    crotch."""
    hip, knee, ankle = b.j("right_hip"), b.j("right_knee"), b.j("right_ankle")
    leg = float((hip - ankle) @ UP)
    y = b.crotch.value - 0.03 * leg
    s = float((hip @ UP - y) / ((hip - knee) @ UP))
    return b.girth("thigh", *b.limb_plane("right_hip", "right_knee", s))


def _calf(b: Body) -> Linear:
    """Calf girth (ISO 8559-1 5.3.22, ANSUR II CALF CIRCUMFERENCE): largest girth of the right calf,
    perpendicular to the shin (knee to ankle joint), 15-55 % of the way down from the knee."""
    return b.extreme_girth("calf", 0.15, 0.55, lambda s: b.limb_plane("right_knee", "right_ankle", s), True)


def _upper_arm(b: Body) -> Linear:
    """Upper-arm girth (ISO 8559-1 5.3.16; the mid-upper-arm circumference): right arm, perpendicular to
    the upper arm, halfway between the acromion and the elbow joint."""
    loop, i = b.acromion("right")
    return b.girth("upper_arm", *b.limb_plane("right_shoulder", "right_elbow", 0.5, start=loop.points[i]))


def _neck(b: Body) -> Linear:
    """Neck girth (ISO 8559-1 5.3.2, ANSUR II NECK CIRCUMFERENCE): perpendicular to the neck's axis (neck
    to head joint) below the larynx, taken as its smallest girth 20-70 % of the way up."""
    return b.extreme_girth("neck", 0.2, 0.7, lambda s: b.limb_plane("neck", "head", s), False)


def _inseam(b: Body) -> Linear:
    """Inside-leg length / crotch height (ISO 8559-1 5.1.15, ANSUR II CROTCH HEIGHT): vertical distance
    from the floor to the crotch."""
    return b.crotch - b.floor


def _shoulder_breadth(b: Body) -> Linear:
    """Biacromial breadth (ISO 7250-1 4.2.8, ANSUR II BIACROMIAL BREADTH): horizontal distance between the
    acromia; each acromion is taken above its shoulder joint (see :meth:`Body.acromion`), so this is close
    to the shoulder joints' distance and can read a few cm under a caliper's."""
    right, left = b.acromion("right"), b.acromion("left")
    axis = b.j("left_shoulder") - b.j("right_shoulder")
    axis[1] = 0.0
    axis /= np.linalg.norm(axis)
    return b.point_linear(*left, axis) - b.point_linear(*right, axis)


def _arm_length(b: Body) -> Linear:
    """Arm length (ISO 8559-1 5.4.? arm length; ANSUR II ACROMION-RADIALE + RADIALE-STYLION LENGTH): right
    arm, acromion to elbow joint plus elbow joint to wrist joint."""
    loop, i = b.acromion("right")
    ac, el, wr = loop.points[i], b.j("right_elbow"), b.j("right_wrist")
    u1 = (el - ac) / np.linalg.norm(el - ac)
    u2 = (wr - el) / np.linalg.norm(wr - el)
    upper = b.joint_linear("right_elbow", u1) - b.point_linear(loop, i, u1)
    fore = b.joint_linear("right_wrist", u2) - b.joint_linear("right_elbow", u2)
    return Linear(
        float(np.linalg.norm(el - ac) + np.linalg.norm(wr - el)),
        np.concatenate([upper.rows, fore.rows]),
        np.concatenate([upper.weights, fore.weights]),
    )


def _sitting_height(b: Body) -> Linear:
    """Sitting height (ISO 7250-1 4.2.1, ANSUR II SITTING HEIGHT) estimated on the standing body: vertex
    minus crotch height. (ANSUR II means: men 918 mm vs stature − crotch height 909 mm; women 858 vs
    856 mm, so the seat lies about at crotch level.)"""
    return b.vertex_top - b.crotch


_FUNCTIONS: dict[str, Callable[[Body], Linear]] = {
    "stature": _stature,
    "mass": _mass,
    "bmi": _bmi,
    "volume": _volume,
    "chest": _chest,
    "under_bust": _under_bust,
    "waist": _waist,
    "hip": _hip,
    "thigh": _thigh,
    "calf": _calf,
    "upper_arm": _upper_arm,
    "neck": _neck,
    "inseam": _inseam,
    "shoulder_breadth": _shoulder_breadth,
    "arm_length": _arm_length,
    "sitting_height": _sitting_height,
}


def check_names(names: tuple[str, ...] | list[str] | None) -> tuple[str, ...]:
    if names is None:
        return MEASUREMENTS
    unknown = [n for n in names if n not in _FUNCTIONS]
    if unknown:
        raise ValueError(f"measurements: unknown {unknown}; expected some of {list(MEASUREMENTS)}")
    return tuple(names)


def measure_body(body: Body, names: tuple[str, ...] | list[str] | None = None) -> dict[str, Linear]:
    """Each named measurement (all by default) of ``body`` with its dependence on the vertices."""
    return {n: _FUNCTIONS[n](body) for n in check_names(names)}
