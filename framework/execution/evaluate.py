"""Evaluations of scenes in this process: every scene ends with a result or the reason it failed."""
from __future__ import annotations

from typing import NamedTuple

import numpy as np

from .models import model_instance


class Evaluations(NamedTuple):
    """Results of n evaluations of scenes with nv vehicles (SI)."""
    ok: np.ndarray  # (n,) bool: the model returned a usable outcome
    rest: np.ndarray  # (n, nv, 3) x, y, heading at the end (NaN where failed)
    contact: np.ndarray  # (n, nv, 4) x, y, heading, speed at first contact
    n_impacts: np.ndarray  # (n,) int
    end_speed: np.ndarray  # (n, nv) speed of each CG at the end [m/s]
    at_rest: np.ndarray  # (n, nv) bool: at rest at the end (crashlab.outcome.REST_SPEED, REST_YAW_RATE)
    reason: np.ndarray  # (n,) object: "" or why the evaluation failed (one line)
    scores: np.ndarray  # (n, k) the caller's scorer's numbers of each outcome (k = 0 without a scorer)


def empty_evaluations(n: int, nv: int, reason: str = "not evaluated", k: int = 0) -> Evaluations:
    return Evaluations(np.zeros(n, bool), np.full((n, nv, 3), np.nan), np.full((n, nv, 4), np.nan),
                       np.zeros(n, int), np.full((n, nv), np.nan), np.zeros((n, nv), bool),
                       np.array([reason] * n, dtype=object), np.full((n, k), np.nan))


def _n_scores(scorer) -> int:
    return 0 if scorer is None else int(scorer.n_residuals)


def _put(dst: Evaluations, start: int, src: Evaluations) -> None:
    for a, b in zip(dst, src):
        a[start:start + len(b)] = b


def _fail(dst: Evaluations, idx, reason: str) -> None:
    dst.ok[idx] = False
    dst.reason[idx] = reason


def _one_line(text: str, limit: int = 300) -> str:
    text = " ".join(str(text).split())
    return text if len(text) <= limit else text[:limit - 3] + "..."


def outcome_reason(o) -> str:
    """Why an Outcome with outcome_ok False failed: the physics guard's findings first, else its warnings."""
    warnings = [str(w) for w in getattr(o, "warnings", ()) or ()]
    guard = [w for w in warnings if w.startswith("physics guard")]
    return _one_line("; ".join(guard or warnings) or "the model reported a failed run (no reason given)")


def _exception_reason(err: BaseException) -> str:
    return _one_line(f"model raised {type(err).__name__}: {err}")


def _vectorised(model) -> bool:
    """Whether the model has a simulate_batch of its own (then a batch is one call, timed as a whole)."""
    from .model import CollisionModel
    own = getattr(type(model), "simulate_batch", None)
    return own is not None and own is not CollisionModel.simulate_batch


def _single_thread():
    try:
        import numba
        numba.set_num_threads(1)
    except Exception:  # noqa: BLE001 - numba is optional for foreign models
        pass


def evaluate_scenes(model_name: str, options_items: tuple, scenes: list, single_thread: bool = False,
                    scorer=None) -> Evaluations:
    """Simulate scenes in this process. A simulation that raises or fails is recorded with its reason,
    never propagated; when the batch call raises, the scenes are simulated one by one so a bad scene
    fails alone. scorer: scores each outcome where it was simulated (module docstring)."""
    if single_thread:
        _single_thread()
    n, nv = len(scenes), len(scenes[0].vehicles)
    res = empty_evaluations(n, nv, k=_n_scores(scorer))
    try:
        model = model_instance(model_name, options_items)
    except Exception as err:  # noqa: BLE001
        _fail(res, slice(None), _one_line(f"model could not be built: {type(err).__name__}: {err}"))
        return res
    batch = scorer is None or not scorer.needs_trajectory
    return evaluations_of(simulate_each(model, scenes, batch=batch), nv, scorer)


def simulate_each(model, scenes, batch: bool = True) -> list:
    """The Outcome of every scene, an exception in place of the outcome of a scene whose simulation raised:
    model.simulate_batch (batch=True), or, when it raises or returns another count, model.simulate scene by
    scene, so that a bad scene fails alone."""
    scenes = list(scenes)
    if batch:
        try:
            outs = list(model.simulate_batch(scenes))
            if len(outs) == len(scenes):
                return outs
        except Exception:  # noqa: BLE001 - one by one, so one bad scene fails alone
            pass
    outs = []
    for s in scenes:
        try:
            outs.append(model.simulate(s))
        except Exception as err:  # noqa: BLE001
            outs.append(err)
    return outs


def evaluations_of(outcomes, nv: int, scorer=None) -> Evaluations:
    """Evaluations of Outcomes (or exceptions in their place): an exception or a failed Outcome fails with its
    reason; a non-finite rest pose fails; an Outcome without final velocities counts as at rest. With a
    scorer, its numbers of the outcomes (a scorer that raises fails them all, with its reason)."""
    res = empty_evaluations(len(outcomes), nv, k=_n_scores(scorer))
    for k, o in enumerate(outcomes):
        if isinstance(o, BaseException):
            res.reason[k] = _exception_reason(o)
            continue
        if o is None:
            res.reason[k] = "the model returned no outcome"
            continue
        if not getattr(o, "outcome_ok", False):
            res.reason[k] = outcome_reason(o)
            continue
        rest = np.asarray(o.rest_si, float)
        if rest.shape != (nv, 3) or not np.all(np.isfinite(rest)):
            res.reason[k] = "non-finite rest pose"
            continue
        res.ok[k], res.reason[k] = True, ""
        res.rest[k] = rest
        contact = getattr(o, "contact_si", None)
        if contact is not None:
            res.contact[k] = contact
        diag = getattr(o, "diagnostics", {}) or {}
        res.n_impacts[k] = diag["episodes"] if "episodes" in diag else len(o.impact_rows)
        final = getattr(o, "final_si", None)
        if final is None:  # an outcome without velocities: nothing says it moves
            res.at_rest[k] = True
            continue
        final = np.asarray(final, float)
        speed = getattr(o, "end_speed_si", None)
        res.end_speed[k] = np.hypot(final[:, 0], final[:, 1]) if speed is None else speed
        mask = getattr(o, "at_rest_mask", None)
        if mask is None:  # an Outcome of an earlier crashlab: the same rule as crashlab.outcome
            mask = (res.end_speed[k] <= 0.1) & (np.abs(final[:, 2]) <= 0.1)
        res.at_rest[k] = mask
    if scorer is not None:
        try:
            res.scores[:] = scorer.residuals(outcomes)
        except Exception as err:  # noqa: BLE001 - the batch is unscored: failed, with the reason
            _fail(res, slice(None), _one_line(f"scoring the outcome raised {type(err).__name__}: {err}"))
    return res
