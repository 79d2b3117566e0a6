"""The layering rule (README: Architecture), read from the source with ast:

- a model package imports only the framework (crashlab, crashlab.<module>), crashlab.models.common,
  its own package and third-party libraries: models build on a common layer, never on each other;
- crashlab.models.common imports only the framework and third-party libraries;
- the framework never imports a model, an optimizer or the reconstruction; only the entry points at the
  top (cli.py, and the package's `crashlab.load_study`) reach the reconstruction and the comparison studies.
"""
import ast
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
MODELS = REPO / "models"
FRAMEWORK_MODULES = {p.stem for p in (REPO / "framework").glob("*.py")} | {"vehicles"}


def _imports(path: Path, package: str):
    """Absolute module names imported by a file that lies in package `package` (relative imports resolved)."""
    tree = ast.parse(path.read_text(), filename=str(path))
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            for a in node.names:
                yield a.name
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")
                base = base[:len(base) - (node.level - 1)]
                yield ".".join(base + ([node.module] if node.module else []))
            else:
                yield node.module


def _allowed_for_model(name: str, own: str) -> bool:
    if not name.startswith("crashlab"):
        return True  # third-party or the standard library
    parts = name.split(".")
    if len(parts) == 1 or (parts[1] in FRAMEWORK_MODULES and parts[1] not in ("models",)):
        return True  # the framework
    return name.startswith("crashlab.models.common") or name.startswith(own)


def _model_packages():
    return sorted(p.name for p in MODELS.iterdir() if (p / "__init__.py").is_file())


@pytest.mark.parametrize("pkg", _model_packages())
def test_models_build_on_framework_and_common_only(pkg):
    own = f"crashlab.models.{pkg}"
    bad = []
    for f in sorted((MODELS / pkg).rglob("*.py")):
        package = ".".join([own, *f.relative_to(MODELS / pkg).parent.parts])
        for name in _imports(f, package):
            ok = _allowed_for_model(name, own) if pkg != "common" else \
                (_allowed_for_model(name, own) and not name.startswith("crashlab.models.") or
                 name.startswith("crashlab.models.common"))
            if not ok:
                bad.append(f"{f.relative_to(REPO)} imports {name}")
    assert not bad, "\n".join(bad)


def test_framework_imports_no_model_optimizer_or_reconstruction():
    bad = []
    for f in sorted((REPO / "framework").glob("*.py")):
        for name in _imports(f, "crashlab"):
            entry = f.name in ("cli.py", "__init__.py") and name.startswith(("crashlab.reconstruction",
                                                                             "crashlab.comparison"))
            if name.startswith(("crashlab.models", "crashlab.optimizers", "crashlab.reconstruction",
                                "crashlab.comparison")) and not entry:
                bad.append(f"framework/{f.name} imports {name}")
    assert not bad, "\n".join(bad)


@pytest.mark.parametrize("pkg", ["reconstruction", "comparison"])
def test_applications_reach_models_through_the_registry(pkg):
    """The reconstruction and the comparison studies name models and optimizers, never import one."""
    bad = [f"{f.relative_to(REPO)} imports {name}" for f in sorted((REPO / pkg).glob("*.py"))
           for name in _imports(f, f"crashlab.{pkg}") if name.startswith(("crashlab.models", "crashlab.optimizers"))]
    assert not bad, "\n".join(bad)
