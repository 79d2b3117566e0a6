"""Keyword-option checking shared by the optimizer factories.

The framework's registry calls every optimizer with keyword options only. An option that no
factory understands must fail loudly instead of being dropped, so each factory checks its
keywords against the names it (and the pymoo classes it wraps) really accepts.
"""

from __future__ import annotations

import inspect
from collections.abc import Iterable, Mapping


def init_parameter_names(cls: type) -> set[str]:
    """Names of the keyword parameters of ``cls.__init__`` and of every ``__init__`` up its MRO."""
    names: set[str] = set()
    for klass in inspect.getmro(cls):
        init = klass.__dict__.get("__init__")
        if init is None:
            continue
        for param in inspect.signature(init).parameters.values():
            if param.kind in (param.POSITIONAL_OR_KEYWORD, param.KEYWORD_ONLY):
                names.add(param.name)
    names.discard("self")
    return names


def reject_unknown_options(owner: str, options: Mapping[str, object], allowed: Iterable[str]) -> None:
    """Raise ``TypeError`` naming every key of ``options`` that is not in ``allowed``."""
    unknown = sorted(set(options) - set(allowed))
    if unknown:
        raise TypeError(f"{owner}() got unexpected option(s): {', '.join(unknown)}")
