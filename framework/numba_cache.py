"""Numba's cache directory, keyed on the crashlab sources (imported first by crashlab)."""
import os


def key_cache_dir() -> None:
    """Numba's on-disk cache keys a compiled function on its own file only, not on the modules it calls
    into (geometry, tyre forces, impact laws); a stale kernel would silently run old physics. Keying the
    cache directory on the state of every crashlab source file makes any edit recompile. A user's own
    NUMBA_CACHE_DIR is respected; nothing is done once numba is imported."""
    import hashlib
    import sys
    from pathlib import Path
    if "NUMBA_CACHE_DIR" in os.environ or "numba" in sys.modules:
        return
    root = Path(__file__).resolve().parent
    dirs = {root, root.parent / "models", root.parent / "optimizers", root / "models", root / "optimizers"}
    h = hashlib.sha1()
    for d in sorted(p for p in dirs if p.is_dir()):
        for f in sorted(d.rglob("*.py")):
            st = f.stat()
            h.update(f"{f}:{st.st_size}:{st.st_mtime_ns}".encode())
    base = Path(os.environ.get("XDG_CACHE_HOME", Path.home() / ".cache")) / "crashlab" / "numba"
    os.environ["NUMBA_CACHE_DIR"] = str(base / h.hexdigest()[:16])


key_cache_dir()
