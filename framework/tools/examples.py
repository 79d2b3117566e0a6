"""The bundled examples: the scene, study and validation files of the repository's studies/, installed as
package data `crashlab.examples`, and the library's vehicle files (crashlab.vehicles). Every command's
default input comes from here, so an installed wheel works without the repository.

`crashlab examples` lists them; `crashlab examples copy DIR` writes them out (DIR/<folder>/<file>, the
vehicle files in DIR/vehicles/) for a user to run and edit.
"""
from __future__ import annotations

import shutil
from importlib import resources
from pathlib import Path

from ..errors import InputError

SUFFIXES = (".toml", ".md", ".py", ".csv")  # what is bundled: files, docs, scripts, published data


def root() -> Path:
    """The folder of the bundled examples (the repository's studies/ in a checkout)."""
    return Path(str(resources.files("crashlab.examples")))


def path(relative: str) -> Path:
    """A bundled example by its path relative to the examples' folder, e.g. 'pc_crash/side.toml'."""
    return root() / relative


def _files(folder: Path, prefix: str = ""):
    for p in sorted(folder.rglob("*")):
        rel = p.relative_to(folder)
        if p.is_file() and p.suffix in SUFFIXES and "__pycache__" not in rel.parts and p.name != "__init__.py":
            yield prefix + rel.as_posix(), p


def files() -> list[tuple[str, Path]]:
    """(relative path, file) of every bundled example and library vehicle, in order."""
    vehicles = Path(str(resources.files("crashlab") / "vehicles"))
    return list(_files(root())) + list(_files(vehicles, "vehicles/"))


def describe(p: Path) -> str:
    """What a file is: a scene's or study's `name`, a vehicle's `name`, else its first comment or doc line."""
    if p.suffix == ".toml":
        import tomllib
        try:
            data = tomllib.loads(p.read_text())
        except (tomllib.TOMLDecodeError, UnicodeDecodeError):
            data = {}
        for key in ("name", "title"):
            if isinstance(data.get(key), str):
                return data[key]
    for line in p.read_text(errors="replace").splitlines():
        line = line.strip().lstrip("#").strip().strip('"').strip()
        if line:
            return line[:100]
    return ""


def copy(dest: str | Path) -> list[Path]:
    """Write every bundled example and library vehicle under `dest` (which must be new or empty)."""
    dest = Path(dest)
    if dest.exists() and (not dest.is_dir() or any(dest.iterdir())):
        raise InputError("command line", "examples copy DIR", f"{dest} exists and is not an empty folder")
    written = []
    try:
        dest.mkdir(parents=True, exist_ok=True)
        for rel, src in files():
            out = dest / rel
            out.parent.mkdir(parents=True, exist_ok=True)
            shutil.copyfile(src, out)
            written.append(out)
    except OSError as err:  # a parent that is a file, a folder that cannot be created or written
        where = f": {err.filename}" if err.filename else ""
        raise InputError(str(dest), "examples copy DIR", f"cannot write there ({err.strerror or err}{where})") from None
    return written
