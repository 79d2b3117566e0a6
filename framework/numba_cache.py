"""Where numba keeps the compiled models: a directory keyed on the crashlab sources.

Numba's on-disk cache keys a compiled function on its own file only, not on the modules it calls into
(geometry, tyre forces, impact laws); a stale kernel would silently run old physics. `configure()` points
numba's cache (numba.config.CACHE_DIR; the environment is left as it is) at
~/.cache/crashlab/numba/<key> (XDG_CACHE_HOME respected), the key taken from the size and time of every
crashlab source file, so any edit recompiles. The package of the compiled models (crashlab.models) calls it
when it is imported, before any kernel is compiled; worker processes import it too and find the same
directory. A user's NUMBA_CACHE_DIR wins: then nothing is changed.
"""
from __future__ import annotations

import hashlib
import os
from pathlib import Path


def cache_dir() -> Path:
    """~/.cache/crashlab/numba/<key of the crashlab sources>."""
    root = Path(__file__).resolve().parent
    dirs = {root, root.parent / "models", root.parent / "optimizers", root / "models", root / "optimizers"}
    h = hashlib.sha1()
    for d in sorted(p for p in dirs if p.is_dir()):
        for f in sorted(d.rglob("*.py")):
            st = f.stat()
            h.update(f"{f}:{st.st_size}:{st.st_mtime_ns}".encode())
    base = Path(os.environ.get("XDG_CACHE_HOME", Path.home() / ".cache")) / "crashlab" / "numba"
    return base / h.hexdigest()[:16]


def configure() -> Path | None:
    """Numba's cache directory set to cache_dir(), unless the user set NUMBA_CACHE_DIR (then None)."""
    if os.environ.get("NUMBA_CACHE_DIR"):
        return None
    from numba.core import config
    path = cache_dir()
    config.CACHE_DIR = str(path)
    return path


def is_cached(package: str) -> bool:
    """Whether numba's cache holds compiled functions of a package of crashlab's models (its folder name, e.g.
    "impulse"): the cache directory has a folder for it (numba names it <folder>_<hash of its path>) with an
    index file in it. False when unknown (no cache directory)."""
    from numba.core import config
    root = Path(config.CACHE_DIR or "")
    if not config.CACHE_DIR or not root.is_dir():
        return False
    return any(next(d.glob("*.nbi"), None) is not None for d in root.glob(f"{package}_*") if d.is_dir())
