"""Finding the model file that ``create(model_path, model_type=..., gender=..., ext=...)`` means.

The one locator: :func:`smplcore.create`, :class:`smplcore.BodyModel`, ``smplcore demo``, ``smplcore export``
and ``smplcore process`` all find their model file here. A folder may hold the files

* directly or in a sub-folder named after the model type (``models/smplx/SMPLX_NEUTRAL.npz``, smplx's layout);
* under smplx's names (``SMPL_NEUTRAL.pkl``, ``SMPLH_FEMALE.pkl``, ``SMPLX_MALE.npz``, ``MANO_RIGHT.pkl``,
  ``FLAME_NEUTRAL.pkl``) or the downloads' own (``basicModel_f_lbs_10_207_0_v1.0.0.pkl``,
  ``basicmodel_neutral_lbs_10_207_0_v1.1.0.pkl``, ``SMPLH_female.pkl``, ``SMPLX_NEUTRAL_2020.npz``,
  ``generic_model.pkl``, ``male_model.pkl``, ``flame2023.pkl``), matched without regard to case;
* in the AMASS / human_body_prior layout ``<folder>/[<model_type>/]<gender>/model.npz``.

The requested format (``ext``, default smplx's per model: :func:`default_ext`) is tried first, then the other
one (``.pkl`` / ``.npz``).
"""

from __future__ import annotations

import re
from pathlib import Path

from smplcore.errors import ModelFileError, warn
from smplcore.family.specs import get_spec
from smplcore.io.open_model import open_model_path

OPEN_MODEL_PATH = open_model_path("neutral")
EXTENSIONS = ("pkl", "npz")


def default_ext(model_type: str) -> str:
    """smplx's default file format per model: ``npz`` for SMPL-X, ``pkl`` for the others."""
    return "npz" if get_spec(model_type).model_type == "smplx" else "pkl"


def official_names(model_type: str, gender: str, ext: str) -> list[str]:
    """File names that hold ``model_type`` of ``gender`` in ``ext`` (``*``: a version; any case matches).

    ``gender`` is ``neutral``, ``male`` or ``female`` (for MANO ``right`` or ``left``). The first name is
    smplx's; the others are the names the downloads use.
    """
    spec = get_spec(model_type)
    key = spec.model_type
    stem = spec.file_stem.format(GENDER=gender.upper(), SIDE=gender.upper())
    names = [f"{stem}.{ext}"]
    if key == "smpl":
        short = {"female": "f", "male": "m"}.get(gender, gender)
        names.append(f"basicModel_{short}_lbs_10_207_0_v*.{ext}")
    elif key == "smplx":
        names.append(f"{stem}_2020.{ext}")  # the SMPL-X 2020 neutral model
    elif key == "flame":
        names += [f"generic_model.{ext}", f"flame2023.{ext}"] if gender == "neutral" else [f"{gender}_model.{ext}"]
    return names


def _children(folder: Path) -> dict[str, Path]:
    """``folder``'s entries by lower-case name (empty when it is not a readable folder)."""
    try:
        return {p.name.lower(): p for p in folder.iterdir()}
    except OSError:
        return {}


def _match(entries: dict[str, Path], name: str) -> Path | None:
    """The file among ``entries`` called ``name`` (any case; ``*`` matches a version), the newest version first."""
    name = name.lower()
    if "*" not in name:
        found = entries.get(name)
        return found if found is not None and found.is_file() else None
    pattern = re.compile(re.escape(name).replace(r"\*", r"[0-9][0-9.]*"))
    hits = sorted((n for n in entries if pattern.fullmatch(n) and entries[n].is_file()), reverse=True)
    return entries[hits[0]] if hits else None


def _search(folder: Path, model_type: str, gender: str, ext: str) -> tuple[list[tuple[Path, str]], Path | None]:
    """Where ``ext`` files are looked for under ``folder`` (the places tried) and the first one found."""
    key = get_spec(model_type).model_type
    tried: list[tuple[Path, str]] = []
    places = [folder]
    typed = _children(folder).get(key)
    if typed is not None and typed.is_dir() and folder.name.lower() != key:
        places.insert(0, typed)
    for place in places:
        entries = _children(place)
        for name in official_names(key, gender, ext):
            tried.append((place, name))
            found = _match(entries, name)
            if found is not None:
                return tried, found
        amass = entries.get(gender)  # AMASS / human_body_prior: <gender>/model.npz
        tried.append((place, f"{gender}/model.{ext}"))
        if amass is not None and amass.is_dir():
            found = _match(_children(amass), f"model.{ext}")
            if found is not None:
                return tried, found
    return tried, None


def locate_model_file(
    model_path: str | Path | None,
    model_type: str | None = None,
    *,
    gender: str = "neutral",
    ext: str | None = None,
    is_rhand: bool = True,
) -> Path:
    """The file to load.

    ``model_path`` may be a file (used as is) or a folder laid out as the module docstring says.
    ``model_type="open"`` without a path (or with a folder) gives the packaged open model of ``gender``.
    For MANO, ``is_rhand`` picks the side.

    Raises
    ------
    ModelFileError
        no such path, or no matching file in the folder: the message lists the names looked for, the model
        files that are there, and how to fix the call.
    ValueError
        a folder without ``model_type``, or an ``ext`` other than ``pkl`` / ``npz``.
    """
    if model_path is None or str(model_path) == "":
        if model_type is not None and get_spec(model_type).model_type == "open":
            return open_model_path(gender)
        raise ValueError(
            "model_path: a model file or folder is needed (or model_type='open' for the packaged open model)"
        )
    path = Path(model_path).expanduser()
    if path.exists() and not path.is_dir():
        return path  # a file (or a FIFO, device, ...: the loader refuses those clearly)
    if not path.exists():
        raise ModelFileError(path, "no such file or folder; pass the model file or the folder that holds it")
    if model_type is None:
        raise ValueError(f"model_type: {path} is a folder; say which model type to load from it")
    spec = get_spec(model_type)
    if spec.model_type == "open":
        warn(
            f"model_path: {path} is a folder, and model_type='open' is the packaged open model: the folder is "
            "not used (pass model_path=None, or the .npz file of an open model to load that one)"
        )
        return open_model_path(gender)
    ext = (ext or default_ext(spec.model_type)).lstrip(".").lower()
    if ext not in EXTENSIONS:
        raise ValueError(f"ext: expected 'pkl' or 'npz', got {ext!r}")
    who = ("right" if is_rhand else "left") if spec.model_type == "mano" else str(gender).strip().lower()
    if who not in ("neutral", "male", "female", "right", "left"):
        meant = {"m": "male", "f": "female", "n": "neutral", "man": "male", "woman": "female"}.get(who)
        raise ValueError(
            f"gender: expected 'neutral', 'male' or 'female', got {gender!r}"
            + (f" (did you mean {meant!r}?)" if meant else "")
        )
    tried: list[tuple[Path, str]] = []
    for e in (ext, *(x for x in EXTENSIONS if x != ext)):
        places, found = _search(path, spec.model_type, who, e)
        if found is not None:
            return found
        tried += places
    raise _not_found(path, spec.model_type, who, ext, tried)


def _not_found(path: Path, model_type: str, who: str, ext: str, tried: list[tuple[Path, str]]) -> ModelFileError:
    spec = get_spec(model_type)

    def shown(place: Path, name: str = "") -> str:
        rel = place.relative_to(path) if place != path else Path()
        return str(rel / name) if name else (f"{rel}/" if str(rel) != "." else "./")

    looked = ", ".join(dict.fromkeys(shown(place, name) for place, name in tried))
    present = sorted(
        shown(p.parent, p.name)
        for p in [*path.glob("*"), *path.glob("*/*"), *path.glob("*/*/*")]
        if p.suffix.lower() in (".pkl", ".npz") and p.is_file()
    )
    side = "is_rhand" if model_type == "mano" else "gender"
    smplx_name = spec.file_stem.format(GENDER=who.upper(), SIDE=who.upper()) + f".{ext}"
    fix = (
        f"put the official {spec.display_name} file there (e.g. {path / spec.model_type / smplx_name}), "
        f"pass the file itself as model_path, or pick another model_type / {side} / ext"
    )
    return ModelFileError(
        path,
        f"no {who} {spec.display_name} model (model_type={model_type!r}, {side}={who!r}, ext={ext!r}); "
        f"looked for {looked}; model files here: {', '.join(present[:20]) or 'none'}"
        f"{' …' if len(present) > 20 else ''}. To fix: {fix}",
    )


def read_model(
    model_path: str | Path | None,
    model_type: str | None = None,
    *,
    gender: str = "neutral",
    ext: str | None = None,
    is_rhand: bool = True,
):
    """Locate and load a model: :func:`locate_model_file` then :func:`smplcore.io.load_model`.

    For a folder, ``gender`` (and for MANO ``is_rhand``) choose the file and are recorded; for a
    file, they are taken from its name where it states them.
    """
    from smplcore.io.model_files import load_model

    path = locate_model_file(model_path, model_type, gender=gender, ext=ext, is_rhand=is_rhand)
    given_file = model_path is not None and str(model_path) != "" and Path(model_path).is_file()
    if model_type is not None and get_spec(model_type).model_type == "mano" and not given_file:
        gender = "right" if is_rhand else "left"
    return load_model(path, model_type=model_type, gender=None if given_file else gender)
