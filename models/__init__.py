"""The built-in collision models (crashlab.models.<name>) and the physics they share (crashlab.models.common).
Importing the package points numba's cache at a directory keyed on the crashlab sources
(crashlab.numba_cache) before any kernel compiles."""
from crashlab.numba_cache import configure as _configure_numba_cache

_configure_numba_cache()
