"""Questions asked of a posterior (`[[questions]] expr = "V1.speed > 50"` in a study file).

An expression is a boolean over the variable labels (V1.speed, V2.heading, impact.restitution, road.friction,
V1.actions.0.t, ...), numbers, + - * /, the comparisons < <= > >= == != (chained as in Python: 40 < V1.speed
<= 60), and, or, not and parentheses. It is parsed by Python's own parser (`ast`, mode "eval") after each
label is replaced by a placeholder name, and then walked with a whitelist of node kinds: anything else (a
call, an attribute, a subscript, a string, `>>`, ...) is refused, nothing is ever evaluated by Python. The
probability of a question is the share of the posterior's samples where it holds (its standard error:
crashlab.reconstruction.infer_report).
"""
from __future__ import annotations

import ast
import math
import operator
import re
from dataclasses import dataclass

import numpy as np

from crashlab.errors import InputError

_COMPARE = {ast.Lt: np.less, ast.LtE: np.less_equal, ast.Gt: np.greater, ast.GtE: np.greater_equal,
            ast.Eq: np.equal, ast.NotEq: np.not_equal}
_ARITH = {ast.Add: np.add, ast.Sub: np.subtract, ast.Mult: np.multiply, ast.Div: np.divide}
_SYMBOL = {ast.RShift: ">>", ast.LShift: "<<", ast.Pow: "**", ast.Mod: "%", ast.FloorDiv: "//",
           ast.BitAnd: "&", ast.BitOr: "|", ast.BitXor: "^", ast.MatMult: "@", ast.Is: "is", ast.IsNot: "is not",
           ast.In: "in", ast.NotIn: "not in", ast.Invert: "~"}
_PLACEHOLDER = "_q{}_"


@dataclass
class Question:
    name: str
    expr: str
    fn: object  # columns dict -> boolean array
    names: tuple[str, ...]  # the labels it reads, sorted

    def probability(self, columns: dict) -> float:
        hold = np.asarray(self.fn(columns), bool)
        return float(np.mean(hold)) if hold.size else math.nan


def _refused(node) -> str:
    what = _SYMBOL.get(type(getattr(node, "op", None))) or _SYMBOL.get(type(node))
    if isinstance(node, ast.Compare):
        what = next((_SYMBOL.get(type(o)) for o in node.ops if type(o) not in _COMPARE), None)
    return f"{what or type(node).__name__} is not allowed"


class _Compiler:
    """ast node -> (kind, function of the columns dict), kind "bool" or "num"."""

    def __init__(self, labels: dict):
        self.labels = labels  # placeholder -> label
        self.used: set[str] = set()

    def bool_(self, node, word):
        kind, fn = self.node(node)
        if kind != "bool":
            raise ValueError(f"'{word}' needs comparisons on both sides")
        return fn

    def num(self, node, word):
        kind, fn = self.node(node)
        if kind != "num":
            raise ValueError(f"'{word}' needs numbers")
        return fn

    def node(self, n):
        if isinstance(n, ast.BoolOp) and type(n.op) in (ast.And, ast.Or):
            word = "and" if isinstance(n.op, ast.And) else "or"
            fns = [self.bool_(v, word) for v in n.values]
            join = operator.and_ if word == "and" else operator.or_
            def fn(d, fns=fns, join=join):
                out = fns[0](d)
                for f in fns[1:]:
                    out = join(out, f(d))
                return out
            return "bool", fn
        if isinstance(n, ast.UnaryOp) and isinstance(n.op, ast.Not):
            a = self.bool_(n.operand, "not")
            return "bool", lambda d, a=a: ~a(d)
        if isinstance(n, ast.UnaryOp) and isinstance(n.op, (ast.USub, ast.UAdd)):
            a = self.num(n.operand, "-" if isinstance(n.op, ast.USub) else "+")
            return ("num", (lambda d, a=a: -a(d)) if isinstance(n.op, ast.USub) else a)
        if isinstance(n, ast.BinOp) and type(n.op) in _ARITH:
            a, b, f = self.num(n.left, "arithmetic"), self.num(n.right, "arithmetic"), _ARITH[type(n.op)]
            return "num", lambda d, f=f, a=a, b=b: f(a(d), b(d))
        if isinstance(n, ast.Compare) and all(type(o) in _COMPARE for o in n.ops):
            sides = [self.node(x) for x in (n.left, *n.comparators)]
            if any(k != "num" for k, _ in sides):
                raise ValueError("comparisons compare numbers")
            parts = [(_COMPARE[type(o)], sides[i][1], sides[i + 1][1]) for i, o in enumerate(n.ops)]
            def fn(d, parts=parts):
                out = None
                for f, a, b in parts:
                    r = f(a(d), b(d))
                    out = r if out is None else out & r
                return out
            return "bool", fn
        if isinstance(n, ast.Constant) and type(n.value) in (int, float):
            v = float(n.value)
            return "num", lambda d, v=v: v
        if isinstance(n, ast.Name) and n.id in self.labels:
            label = self.labels[n.id]
            self.used.add(label)
            return "num", lambda d, v=label: np.asarray(d[v], float)
        if isinstance(n, (ast.Name, ast.Attribute)):
            text = ast.unparse(n)
            for ph, label in self.labels.items():
                text = text.replace(ph, label)
            raise ValueError(f"unknown name {text!r} (variables: {', '.join(self.labels.values())})")
        raise ValueError(_refused(n))


def parse_question(expr: str, names, source="<study>", key="questions.0.expr") -> Question:
    """A Question over the variable labels `names`; InputError naming source and key if it does not parse."""
    labels = {_PLACEHOLDER.format(i): n for i, n in enumerate(names)}
    text = expr
    # longest label first, whole dotted names only (V1.speed is not a part of V1.speed2)
    for ph, label in sorted(labels.items(), key=lambda kv: -len(kv[1])):
        text = re.sub(rf"(?<![\w.]){re.escape(label)}(?![\w.])", ph, text)
    try:
        tree = ast.parse(text.strip(), mode="eval")
        c = _Compiler(labels)
        kind, fn = c.node(tree.body)
        if kind != "bool":
            raise ValueError("not a comparison (e.g. V1.speed > 50)")
    except SyntaxError as err:
        raise InputError(source, key, f"{expr!r} does not parse: {err.msg}") from None
    except ValueError as err:
        raise InputError(source, key, f"{expr!r} does not parse: {err}") from None
    return Question(expr, expr, fn, tuple(sorted(c.used)))
