"""The impulse kernel's stages are inlined at numba's IR level (inline="always") and compiled by
models/impulse/compiler.py, whose one extra pass drops the array copies the inlining leaves (each one a reference
count up and down per run of the stage that LLVM's pruning leaves in simulate_one's loops). A toy loop calling a toy
stage, compiled with and without the pass: the same numbers bit for bit (and as plain Python sums them), and after the
pass no copy of an array is left in the typed IR (counted by a pass of the test's, run right after it)."""
from __future__ import annotations

import numpy as np
from numba import njit
from numba.core import ir, types
from numba.core.compiler import CompilerBase, DefaultPassBuilder
from numba.core.compiler_machinery import FunctionPass, register_pass
from numba.core.typed_passes import NopythonTypeInference

from crashlab.models.impulse.compiler import ElideArrayCopies

COPIES: list[int] = []  # the array copies counted, one entry per compilation


@register_pass(mutates_CFG=False, analysis_only=True)
class CountArrayCopies(FunctionPass):
    _name = "test_count_array_copies"

    def __init__(self):
        FunctionPass.__init__(self)

    def run_pass(self, state):
        COPIES.append(sum(isinstance(s, ir.Assign) and isinstance(s.value, ir.Var)
                          and isinstance(state.typemap[s.target.name], types.Array)
                          for block in state.func_ir.blocks.values() for s in block.body))
        return False


class Plain(CompilerBase):
    def define_pipelines(self):
        pm = DefaultPassBuilder.define_nopython_pipeline(self.state)
        pm.add_pass_after(CountArrayCopies, NopythonTypeInference)
        pm.finalize()
        return [pm]


class Elided(CompilerBase):  # models/impulse/compiler.StagesCompiler with the count after its pass
    def define_pipelines(self):
        pm = DefaultPassBuilder.define_nopython_pipeline(self.state)
        pm.add_pass_after(ElideArrayCopies, NopythonTypeInference)
        pm.add_pass_after(CountArrayCopies, ElideArrayCopies)
        pm.finalize()
        return [pm]


@njit(inline="always")
def _stage(a, b, out, h):
    """A stage: writes out from a and b, returns a scalar."""
    s = 0.0
    for q in range(a.shape[0]):
        out[q] = a[q] + h * b[q]
        s += out[q]
    return s


def _loop(a, b, out, n):
    total = 0.0
    for step in range(n):
        total += _stage(a, b, out, 0.5 / (step + 1))
        for q in range(a.shape[0]):
            a[q] = out[q]
    return total


def test_pass_drops_the_array_copies_and_keeps_the_numbers():
    rng = np.random.default_rng(3)
    a0, b = rng.normal(size=7), rng.normal(size=7)
    a1, a2, o1, o2 = a0.copy(), a0.copy(), np.empty(7), np.empty(7)
    COPIES.clear()
    t1 = njit(pipeline_class=Plain)(_loop)(a1, b, o1, 50)
    t2 = njit(pipeline_class=Elided)(_loop)(a2, b, o2, 50)
    plain, elided = COPIES
    assert plain == 3  # the inlined stage's three array arguments
    assert elided == 0
    assert t1 == t2 and np.array_equal(a1, a2) and np.array_equal(o1, o2)  # bit for bit
    a3, total = a0.copy(), 0.0  # an independent reference: plain Python, the same sums in the same order
    for step in range(50):
        h, s = 0.5 / (step + 1), 0.0
        out = [a3[q] + h * b[q] for q in range(7)]
        for v in out:
            s += v
        total += s
        a3 = np.array(out)
    assert total == t2
