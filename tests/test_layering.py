"""The layering of docs DESIGN ("files -> io -> ModelData -> engine -> model.Rig -> consumers"), held by reading the
source: every import (at module level and inside functions) and every reach-in into a front end's private setup.

Known exceptions are listed by name with the issue that removes them; the test fails when one goes away as well
(so the list only shrinks) and when a new one appears."""

from __future__ import annotations

import ast
import functools
from pathlib import Path

import pytest

SRC = Path(__file__).resolve().parents[1] / "src" / "smplcore"

# The layers, lowest first; a module may import its own layer and those below.
BASE = {"errors", "_deps", "family"}
LAYERS: list[set[str]] = [
    BASE,
    {"io"},
    {"engine"},
    # the model contract and the front ends over it (with smplx's module paths)
    {
        "model",
        "frontend",
        "numpy_model",
        "torch",
        "smplx_compat",
        "body_models",
        "lbs",
        "utils",
        "vertex_ids",
        "joint_names",
        "vertex_joint_selector",
    },
    # what every consumer shares, owned by none: mesh argument checks, UV maps and textures
    {"mesh_args", "uv"},
    # consumers: they use the public API of the layers below and of each other, never internals
    {
        "keypoints",
        "fit",
        "motion",
        "export",
        "render",
        "view",
        "jobs",
        "measure",
        "join",
        "skeletons",
        "cli_options",
    },
    # applications
    {"cli", "cli_options", "demo", "__main__", "<root>"},
]
FRONT_ENDS = {"model", "frontend", "numpy_model", "torch"}
SHARED = LAYERS[4]
CONSUMERS = LAYERS[5]
APPLICATIONS = LAYERS[6]

# (importing module, imported module) pairs that break a rule today, and what removes them.
KNOWN = {
    # the joint_regressors option loads keypoint regressors (issue 24: regressors through one public io entry)
    ("smplcore.frontend.setup", "smplcore.keypoints"),
    # parameter files are read by export (issue 24: one reader of parameter files below view and export)
    ("smplcore.view.sources", "smplcore.export.animation"),
    ("smplcore.export.inputs", "smplcore.motion.sequence"),
}


def _module_name(path: Path) -> str:
    parts = path.relative_to(SRC.parent).with_suffix("").parts
    name = ".".join(parts)
    return name[: -len(".__init__")] if name.endswith(".__init__") else name


def _package(module: str) -> str:
    parts = module.split(".")
    return parts[1] if len(parts) > 1 else "<root>"


@functools.cache
def _modules() -> list[tuple[str, ast.AST]]:
    return [(_module_name(p), ast.parse(p.read_text(), str(p))) for p in sorted(SRC.rglob("*.py"))]


def _imports(tree: ast.AST, module: str) -> set[str]:
    """Every smplcore module ``tree`` imports, at module level or inside a function (relative imports resolved)."""
    out = set()
    package = module if _is_package(module) else module.rsplit(".", 1)[0]
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            out |= {a.name for a in node.names}
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                anchor = package.split(".")
                anchor = anchor[: len(anchor) - node.level + 1]
                base = ".".join(anchor + ([base] if base else []))
            out.add(base)
            # ``from smplcore import fit`` imports the subpackage
            out |= {f"{base}.{a.name}" for a in node.names if (SRC.parent / base.replace(".", "/") / a.name).exists()}
    return {m for m in out if m == "smplcore" or m.startswith("smplcore.")}


def _is_package(module: str) -> bool:
    return (SRC.parent / module.replace(".", "/") / "__init__.py").exists()


def _layer(package: str) -> int:
    for i, layer in enumerate(LAYERS):
        if package in layer:
            return i
    raise AssertionError(f"smplcore.{package}: not in any layer of tests/test_layering.py; add it to one")


def _violations() -> set[tuple[str, str]]:
    found = set()
    for module, tree in _modules():
        src = _package(module)
        for target in _imports(tree, module):
            dst = _package(target)
            if dst == src or target == "smplcore":
                continue
            upward = _layer(dst) > _layer(src)
            # consumers use the public packages of io and of each other, never their modules
            internal = src in CONSUMERS and (dst == "io" or dst in CONSUMERS) and target.count(".") > 1
            # consumers use the front ends' public API (smplcore.BodyModel, smplcore.create), not their insides
            front_end = src in CONSUMERS and (dst == "frontend" or (dst == "torch" and target.count(".") > 1))
            if upward or internal or front_end:
                found.add((module, target))
    return found


def test_every_package_is_in_a_layer():
    for module, _ in _modules():
        _layer(_package(module))


def test_imports_follow_the_layers():
    found = _violations()
    new = sorted(found - KNOWN)
    assert not new, f"imports against the layering (see DESIGN.md): {new}"


def test_known_exceptions_still_exist():
    gone = sorted(KNOWN - _violations())
    assert not gone, f"these exceptions are fixed: remove them from KNOWN in tests/test_layering.py: {gone}"


def _reach_ins(tree: ast.AST) -> list[str]:
    """``x.setup`` (the front end's private setup) and ``setup.data`` / ``setup.spec`` / ... read in ``tree``."""
    private = {"data", "spec", "dmpldirs", "pose_mean", "shapedirs", "exprdirs", "hand_components", "keypoints"}
    out = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Attribute):
            if node.attr == "setup" and not (isinstance(node.value, ast.Name) and node.value.id == "self"):
                out.append(f"line {node.lineno}: .setup")
            elif node.attr in private and isinstance(node.value, ast.Name) and node.value.id == "setup":
                out.append(f"line {node.lineno}: setup.{node.attr}")
            elif node.attr == "_smplcore_fit_body":
                out.append(f"line {node.lineno}: ._smplcore_fit_body")
        elif isinstance(node, ast.Call) and getattr(node.func, "attr", None) == "__setattr__":
            if isinstance(node.func, ast.Attribute) and getattr(node.func.value, "id", None) == "object":
                if node.args and not (isinstance(node.args[0], ast.Name) and node.args[0].id == "self"):
                    out.append(f"line {node.lineno}: object.__setattr__ on another object")
    return out


@pytest.mark.parametrize("package", sorted(SHARED | CONSUMERS | APPLICATIONS))
def test_consumers_read_the_rig_not_the_front_ends_setup(package):
    found = {module: hits for module, tree in _modules() if _package(module) == package and (hits := _reach_ins(tree))}
    assert not found, f"reach-ins into a front end's private setup (read model.rig instead): {found}"


def test_the_reach_in_check_sees_reach_ins():
    code = "def f(model):\n    setup = model.setup\n    return setup.data.J_regressor, setup.spec\n"
    assert len(_reach_ins(ast.parse(code))) == 3
    assert not _reach_ins(ast.parse("def f(model):\n    return model.rig.joint_regressor\n"))
