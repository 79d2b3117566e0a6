"""The numba compiler of the impulse kernel's time loop (kernel.simulate_one): numba's own nopython pipeline and one
pass more, after type inference, that drops the array copies IR inlining leaves behind.

numba inlines a function declared inline="always" at the IR level by assigning each argument to a variable of the
callee's (`S_1 = S`) and running the callee's body on those. An array variable holds a reference: each such copy
costs a reference count up and down (an atomic NRT_incref, NRT_decref) every time the stage runs, which LLVM's
reference-count pruning leaves in place across the stage's loops (measured: about 320 of them in simulate_one, the
kernel 23-33 % slower). After numba's ReconstructSSA (before type inference) most variables have one definition; a
copy `a = b` of an array of the same type, both defined once, that comes before every read of a can be dropped and
each read of a made a read of b: the compiled arithmetic is unchanged (results bit for bit), only the reference
counts go.
"""
from numba.core import ir, ir_utils, types
from numba.core.analysis import compute_cfg_from_blocks
from numba.core.compiler import CompilerBase, DefaultPassBuilder
from numba.core.compiler_machinery import FunctionPass, register_pass
from numba.core.typed_passes import NopythonTypeInference


@register_pass(mutates_CFG=False, analysis_only=False)
class ElideArrayCopies(FunctionPass):
    """Drop each copy `a = b` between two arrays of the same type that are each defined once (SSA form), where the
    copy comes before every read of a (it dominates them: b cannot have changed in between), and read b wherever a
    was read."""

    _name = "elide_array_copies"

    def __init__(self):
        FunctionPass.__init__(self)

    def run_pass(self, state):
        blocks, typemap = state.func_ir.blocks, state.typemap
        n_defs, uses = {}, {}
        for label, block in blocks.items():
            for index, stmt in enumerate(block.body):
                if isinstance(stmt, ir.Assign):
                    n_defs[stmt.target.name] = n_defs.get(stmt.target.name, 0) + 1
                for var in stmt.list_vars():
                    uses.setdefault(var.name, []).append((label, index))
        dominators = compute_cfg_from_blocks(blocks).dominators()
        copies = {}
        for label, block in blocks.items():
            for index, stmt in enumerate(block.body):
                if (isinstance(stmt, ir.Assign) and isinstance(stmt.value, ir.Var)
                        and n_defs[stmt.target.name] == 1 and n_defs.get(stmt.value.name, 0) == 1
                        and isinstance(typemap[stmt.target.name], types.Array)
                        and typemap[stmt.target.name] == typemap[stmt.value.name]
                        and all(label in dominators[at] and (at != label or i > index)  # read after the copy only
                                for at, i in uses[stmt.target.name] if (at, i) != (label, index))):
                    copies[stmt.target.name] = stmt.value
        if not copies:
            return False
        for name, var in copies.items():  # a copy of a copy reads the first
            while var.name in copies:
                var = copies[var.name]
            copies[name] = var
        for block in blocks.values():
            block.body = [stmt for stmt in block.body
                          if not (isinstance(stmt, ir.Assign) and stmt.target.name in copies)]
            for stmt in block.body:
                ir_utils.replace_vars_stmt(stmt, copies)
        state.func_ir._definitions = ir_utils.build_definitions(blocks)
        return True


class StagesCompiler(CompilerBase):
    """numba's nopython pipeline with ElideArrayCopies after type inference."""

    def define_pipelines(self):
        pm = DefaultPassBuilder.define_nopython_pipeline(self.state)
        pm.add_pass_after(ElideArrayCopies, NopythonTypeInference)
        pm.finalize()
        return [pm]
