"""Questions asked of a posterior (`[[questions]] expr = "V1.speed > 50"` in a study file).

An expression is a boolean over the variable labels (V1.speed, V2.heading, impact.restitution, road.friction,
V1.actions.0.t, ...), numbers, + - * /, the comparisons < <= > >= == != (chained as in Python: 40 < V1.speed
<= 60), and, or, not and parentheses. It is parsed by Python's own parser (`ast`, mode "eval") after each
label is replaced by a placeholder name, and then walked with a whitelist of node kinds: anything else (a
call, an attribute, a subscript, a string, `>>`, ...) is refused, nothing is ever evaluated by Python. The
probability of a question is the share of the posterior's samples where it holds (its standard error:
`answers` below, from the smallest effective sample size of the variables it reads).

Division by zero. A divisor without variables that is 0 (`V1.speed / 0`, `V1.speed / (2 - 2)`) is refused
when the study is loaded (InputError naming the key). A divisor that is 0 in some draws (`V1.speed /
(V2.speed - 50)`) leaves the question undefined in those draws: its probability is the share among the draws
where it is defined, and the answer says in how many it was not (`Answer.undefined`, `Answer.note`); in no
draw is it defined: probability NaN with that note. Every value is checked, not only divisors: a non-finite
sample or an overflow leaves the draw undefined the same way, never a quiet False of a NaN comparison. A number
written beyond the largest float (1e999: infinity) is refused when the study is loaded.
"""
from __future__ import annotations

import ast
import math
import operator
import re
from dataclasses import dataclass

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, ValidationError

from crashlab.errors import InputError

_COMPARE = {ast.Lt: np.less, ast.LtE: np.less_equal, ast.Gt: np.greater, ast.GtE: np.greater_equal,
            ast.Eq: np.equal, ast.NotEq: np.not_equal}
_ARITH = {ast.Add: np.add, ast.Sub: np.subtract, ast.Mult: np.multiply, ast.Div: np.divide}
_SYMBOL = {ast.RShift: ">>", ast.LShift: "<<", ast.Pow: "**", ast.Mod: "%", ast.FloorDiv: "//",
           ast.BitAnd: "&", ast.BitOr: "|", ast.BitXor: "^", ast.MatMult: "@", ast.Is: "is", ast.IsNot: "is not",
           ast.In: "in", ast.NotIn: "not in", ast.Invert: "~"}
_PLACEHOLDER = "_q{}_"


class QuestionFile(BaseModel):
    """A `[[questions]]` table: an expression of the posterior's variables answered with its probability or
    distribution (crashlab infer)."""
    model_config = ConfigDict(extra="forbid")
    expr: str = Field(min_length=1, max_length=2000, description="expression of the variables' labels (as in "
                      "posterior.csv), e.g. `car.speed > 50`: numbers, + - * /, comparisons, and, or, not, ( )")
    name: str | None = Field(default=None, description="label of the answer in summary.md; default the expr")


@dataclass
class Answer:
    """A question's answer on the draws: its name (the study's `name`, else the expression) in every output."""
    name: str
    expr: str
    probability: float  # share of the defined draws where it holds; NaN when none is defined
    standard_error: float  # Monte Carlo: sqrt(p (1 - p) / ESS), ESS the smallest of its variables'
    draws: int
    undefined: int  # draws where a divisor is 0 or a value is not finite

    @property
    def note(self) -> str:
        """'' or why some draws do not count, for the summary, the table and the report."""
        if not self.undefined:
            return ""
        return (f"undefined in {self.undefined} of {self.draws} draws (a division by zero or a non-finite value), "
                "not counted")


@dataclass
class Question:
    name: str
    expr: str
    fn: object  # columns dict -> (holds, defined): two boolean arrays
    names: tuple[str, ...]  # the labels it reads, sorted

    def evaluate(self, columns: dict) -> tuple[np.ndarray, np.ndarray]:
        """(holds, defined) per draw, both boolean arrays (module docstring)."""
        n = len(next(iter(columns.values()))) if columns else 1
        hold, defined = self.fn(columns)
        return np.broadcast_to(np.asarray(hold, bool), (n,)), np.broadcast_to(np.asarray(defined, bool), (n,))

    def probability(self, columns: dict) -> float:
        """The share of the defined draws where it holds (NaN: none defined)."""
        hold, defined = self.evaluate(columns)
        return float(np.mean(hold[defined])) if defined.any() else math.nan

    def answer(self, columns: dict, ess: float | None = None) -> Answer:
        hold, defined = self.evaluate(columns)
        p = float(np.mean(hold[defined])) if defined.any() else math.nan
        n_eff = max(float(ess if ess is not None else defined.sum()), 1.0)
        se = math.sqrt(max(p * (1.0 - p), 0.0) / n_eff) if defined.any() else math.nan
        return Answer(self.name, self.expr, p, se, int(hold.size), int((~defined).sum()))


def answers(questions, labels, samples, ess) -> list[Answer]:
    """Every question answered on `samples` (draws x variables, columns `labels`), its standard error from the
    smallest effective sample size `ess` (per variable) of the variables it reads (NaN where one of them has
    none: a chain too short for an autocorrelation estimate; the standard error is then NaN too)."""
    cols = {lab: samples[:, j] for j, lab in enumerate(labels)}
    return [q.answer(cols, smallest([ess[labels.index(n)] for n in q.names], len(samples))) for q in questions]


def smallest(values, default=math.nan) -> float:
    """min(values), NaN when any is NaN (min() itself would depend on the order), default when empty (an ESS that
    could not be computed: infer_report.smallest_ess, answers)."""
    values = [float(v) for v in values]
    return default if not values else math.nan if any(map(math.isnan, values)) else min(values)


class _KnownNow(ValueError):
    """A question whose part is decided without a draw: a division by a zero, a comparison of numbers alone."""


def _divide(a, b):
    """a / b, NaN where b is 0 (the draw is undefined; module docstring), without numpy's warning."""
    a, b = np.broadcast_arrays(np.asarray(a, float), np.asarray(b, float))
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        return _finite(np.divide(a, b, out=np.full(a.shape, np.nan), where=b != 0))


def _finite(x):
    """x with its infinities (an overflow) as NaN: an undefined draw, as a division by zero."""
    x = np.asarray(x, float)
    return np.where(np.isinf(x), np.nan, x)


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

    def _reads(self, node) -> set:
        """The labels an already compiled subtree reads."""
        return {self.labels[x.id] for x in ast.walk(node) if isinstance(x, ast.Name) and x.id in self.labels}

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
                out, defined = fns[0](d)
                for f in fns[1:]:
                    h, ok = f(d)
                    out, defined = join(out, h), defined & ok
                return out, defined
            return "bool", fn
        if isinstance(n, ast.UnaryOp) and isinstance(n.op, ast.Not):
            a = self.bool_(n.operand, "not")
            def negate(d, a=a):
                h, ok = a(d)
                return ~h, ok
            return "bool", negate
        if isinstance(n, ast.UnaryOp) and isinstance(n.op, (ast.USub, ast.UAdd)):
            a = self.num(n.operand, "-" if isinstance(n.op, ast.USub) else "+")
            return ("num", (lambda d, a=a: -a(d)) if isinstance(n.op, ast.USub) else a)
        if isinstance(n, ast.BinOp) and type(n.op) in _ARITH:
            a, b, f = self.num(n.left, "arithmetic"), self.num(n.right, "arithmetic"), _ARITH[type(n.op)]
            if f is np.divide:
                if not self._reads(n.right) and np.all(b({}) == 0):  # a divisor without variables: known now
                    raise _KnownNow(f"divides by zero (the divisor {ast.unparse(n.right)} is 0 whatever "
                                    "the draw)")
                return "num", lambda d, a=a, b=b: _divide(a(d), b(d))
            return "num", lambda d, f=f, a=a, b=b: _finite(f(a(d), b(d)))
        if isinstance(n, ast.Compare) and all(type(o) in _COMPARE for o in n.ops):
            sides = [self.node(x) for x in (n.left, *n.comparators)]
            if any(k != "num" for k, _ in sides):
                raise ValueError("comparisons compare numbers")
            parts = [(_COMPARE[type(o)], sides[i][1], sides[i + 1][1]) for i, o in enumerate(n.ops)]
            terms = (n.left, *n.comparators)
            for i, (f, a, b) in enumerate(parts):  # a part without variables (in a chain: 50 > 40 == 1)
                if not self._reads(terms[i]) and not self._reads(terms[i + 1]):
                    part = ast.unparse(ast.Compare(left=terms[i], ops=[n.ops[i]], comparators=[terms[i + 1]]))
                    raise _KnownNow(f"has {part}, a comparison without a variable: always "
                                    f"{'true' if bool(f(a({}), b({}))) else 'false'}")
            def fn(d, parts=parts):
                out, defined = None, True
                for f, a, b in parts:
                    x, y = a(d), b(d)
                    r = f(x, y)
                    out = r if out is None else out & r
                    defined = defined & np.isfinite(x) & np.isfinite(y)
                return out, defined
            return "bool", fn
        if isinstance(n, ast.Constant) and type(n.value) in (int, float):
            try:
                v = float(n.value)
            except OverflowError:  # an integer of more than 309 digits
                v = math.inf
            if not math.isfinite(v):  # 1e999 is read as infinity: no number a draw can be compared with
                raise ValueError("a number beyond 1.8e308 (the largest float) is infinite: give a finite number")
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


def parse_question(expr: str, names, source="<study>", key="questions.0.expr", name: str | None = None) -> Question:
    """A Question over the variable labels `names` (its `name`: the study's, default the expression);
    InputError naming source and key if it does not parse, divides by a zero or compares numbers without
    variables."""
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
    except _KnownNow as err:
        raise InputError(source, key, f"{expr!r} {err}") from None
    except ValueError as err:
        raise InputError(source, key, f"{expr!r} does not parse: {err}") from None
    return Question(name or expr, expr, fn, tuple(sorted(c.used)))


def parse_questions(raw, names, source) -> list[Question]:
    """The study's `[[questions]]` tables (QuestionFile each) over the variable labels `names`: checked when the
    study is loaded (crashlab.reconstruction.study, for every command), InputError naming questions.K.key."""
    from crashlab.input_files import pydantic_error
    if not isinstance(raw, list):
        raise InputError(source, "questions", "a list of tables ([[questions]] expr = \"V1.speed > 50\")")
    out = []
    for k, q in enumerate(raw):
        try:
            qf = QuestionFile.model_validate(q)
        except ValidationError as err:
            raise pydantic_error(source, err, f"questions.{k}.", QuestionFile) from None
        out.append(parse_question(qf.expr, names, source, f"questions.{k}.expr", name=qf.name))
    return out
