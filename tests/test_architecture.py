"""The layering (docs/architecture.md), read from the source with ast, and the import graph without circles.

LAYERS is the table of docs/architecture.md: each layer and the layers it may import. A layer never imports
one above it; models build on the core and the common layer, never on each other; the reconstruction and the
comparison studies reach models and optimizers through the registry, by name. Deferred imports (inside a
function) count as imports.
"""
import ast
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
# folder -> the package it installs as (pyproject.toml [tool.setuptools.package-dir])
ROOTS = {"framework": "crashlab", "models": "crashlab.models", "optimizers": "crashlab.optimizers",
         "reconstruction": "crashlab.reconstruction", "comparison": "crashlab.comparison"}

# layer -> the layers it may import ("own" for a model package: itself)
LAYERS = {
    "core": {"core"},
    "tools": {"core", "tools"},
    "common": {"core", "common"},
    "model": {"core", "common", "own"},
    "optimizers": {"core", "optimizers"},
    "reconstruction": {"core", "tools", "reconstruction"},
    "comparison": {"core", "tools", "comparison"},
    "cli": {"core", "tools", "reconstruction", "comparison", "cli"},
}


def layer_of(module: str) -> str:
    """The layer of a crashlab module name."""
    parts = module.split(".")
    if len(parts) >= 2 and parts[1] in ("tools", "cli", "optimizers", "reconstruction", "comparison"):
        return parts[1]
    if len(parts) >= 2 and parts[1] == "models":
        return "common" if len(parts) >= 3 and parts[2] == "common" else "model"
    return "core"


def modules(repo: Path = REPO) -> dict:
    """crashlab module name -> file, for every .py of the installed packages."""
    out = {}
    for folder, package in ROOTS.items():
        for f in sorted((repo / folder).rglob("*.py")):
            parts = list(f.relative_to(repo / folder).with_suffix("").parts)
            if parts[-1] == "__init__":
                parts = parts[:-1]
            out[".".join([package, *parts])] = f
    return out


def imports(name: str, path: Path, known) -> set:
    """The crashlab modules a file imports (relative imports resolved; `from p import m` names module p.m
    when p.m is a module, else p)."""
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    found = set()
    for node in ast.walk(ast.parse(path.read_text(), filename=str(path))):
        if isinstance(node, ast.Import):
            found.update(a.name for a in node.names)
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")[:len(package.split(".")) - (node.level - 1)]
                mod = ".".join(base + ([node.module] if node.module else []))
            else:
                mod = node.module
            found.update(f"{mod}.{a.name}" if f"{mod}.{a.name}" in known else mod for a in node.names)
    return {m for m in found if m == "crashlab" or m.startswith("crashlab.")}


def graph(repo: Path = REPO) -> dict:
    mods = modules(repo)
    return {m: imports(m, f, mods) - {m} for m, f in mods.items()}


def upward_imports(repo: Path = REPO) -> list:
    bad = []
    for mod, targets in graph(repo).items():
        layer = layer_of(mod)
        own = ".".join(mod.split(".")[:3])
        for t in targets:
            allowed = LAYERS[layer]
            ok = layer_of(t) in allowed or ("own" in allowed and (t == own or t.startswith(own + ".")))
            if not ok:
                bad.append(f"{mod} ({layer}) imports {t} ({layer_of(t)})")
    return sorted(bad)


def circles(repo: Path = REPO) -> list:
    """The strongly connected components of more than one module (scipy's, on the module graph)."""
    import numpy as np
    from scipy.sparse import csr_matrix
    from scipy.sparse.csgraph import connected_components
    g = graph(repo)
    names = sorted(g)
    index = {m: i for i, m in enumerate(names)}
    rows, cols = zip(*[(index[a], index[b]) for a, bs in g.items() for b in bs if b in index])
    adj = csr_matrix((np.ones(len(rows)), (rows, cols)), shape=(len(names), len(names)))
    n, labels = connected_components(adj, directed=True, connection="strong")
    groups = [[names[i] for i in np.flatnonzero(labels == k)] for k in range(n)]
    return [g for g in groups if len(g) > 1]


def test_every_layer_imports_only_the_layers_below_it():
    assert not upward_imports(), "\n".join(upward_imports())


def test_the_import_graph_has_no_circles():
    assert not circles(), circles()


def test_the_table_covers_every_package():
    layers = {layer_of(m) for m in modules()}
    assert layers == set(LAYERS), layers ^ set(LAYERS)


def _copy_sources(tmp_path):
    import shutil
    for folder in ROOTS:
        shutil.copytree(REPO / folder, tmp_path / folder, ignore=shutil.ignore_patterns("__pycache__", "*.toml"))
    return tmp_path


@pytest.mark.parametrize("planted, layer", [
    ("framework/scene.py", "crashlab.reconstruction"),      # the core reaching up
    ("framework/tools/plotting.py", "crashlab.cli"),         # a tool reaching the command line
    ("models/impulse/model.py", "crashlab.models.pymunk"),   # a model building on another
    ("reconstruction/study.py", "crashlab.models.impulse"),  # an application importing a model
])
def test_a_planted_upward_import_fails(tmp_path, planted, layer):
    """The check is not blind: one upward import planted in a copy of the sources is found."""
    repo = _copy_sources(tmp_path)
    f = repo / planted
    f.write_text(f.read_text() + f"\n\ndef _planted():\n    import {layer}  # noqa\n")
    assert any(layer in b for b in upward_imports(repo))


def test_a_planted_circle_fails(tmp_path):
    repo = _copy_sources(tmp_path)
    f = repo / "framework" / "units.py"
    f.write_text(f.read_text() + "\n\ndef _planted():\n    from .scene_file import load_scene  # noqa\n")
    assert any("crashlab.units" in c for c in circles(repo))


def test_every_package_is_in_the_wheel():
    """pyproject.toml lists every package (a package missing there is missing from the installed wheel)."""
    import tomllib
    cfg = tomllib.loads((REPO / "pyproject.toml").read_text())["tool"]["setuptools"]
    listed = set(cfg["packages"])
    packages = {name for name, f in modules().items() if f.name == "__init__.py"}
    assert packages <= listed, sorted(packages - listed)
