"""Questions of a posterior (crashlab.reconstruction.questions, issue 27): a divisor without variables that is
0 is refused when the study is read (one line naming the key); a divisor that is 0 in some draws leaves the
question undefined there and the answer says so (never inf, NaN or a quiet False counted as an answer); a
question's name is in its answer. Before: `V1.speed / 0 > 1` was answered "probability 1.000"."""
from __future__ import annotations

import math

import numpy as np
import pytest

from crashlab.errors import InputError
from crashlab.reconstruction.questions import answers, parse_question

NAMES = ["V1.speed", "V2.speed"]


@pytest.mark.parametrize("expr, divisor", [("V1.speed / 0 > 1", "0"), ("V1.speed / 0.0 > 1", "0.0"),
                                           ("V1.speed / (2 - 2) > 1", "2 - 2"),
                                           ("V1.speed > 1 and 3 / (4 * 0) < V2.speed", "4 * 0"),
                                           ("V2.speed / (V1.speed / (1 - 1)) > 1", "1 - 1")])
def test_a_divisor_that_is_zero_whatever_the_draw_is_refused_at_load(expr, divisor):
    with pytest.raises(InputError) as err:
        parse_question(expr, NAMES, "s.toml", "questions.1.expr")
    line = str(err.value)
    assert line.startswith("s.toml: questions.1.expr: ") and "\n" not in line
    assert "divides by zero" in line and f"the divisor {divisor} is 0" in line


@pytest.mark.parametrize("expr", ["V1.speed / (V2.speed - 50) > 1", "V1.speed / (1 - 0) > 1", "V1.speed / 2 > 1"])
def test_a_divisor_with_variables_or_not_zero_is_accepted(expr):
    parse_question(expr, NAMES)


def test_draws_where_a_divisor_is_zero_are_undefined_and_said_so():
    """4 draws: V2 = 50 (divisor 0) twice, one where the ratio holds, one where it does not; the probability
    is 1/2 over the 2 defined draws (by hand), the answer counts 2 undefined and says so."""
    S = np.array([[60.0, 50.0], [60.0, 40.0], [60.0, 55.0], [10.0, 50.0]])
    q = parse_question("V1.speed / (V2.speed - 50) > 1", NAMES, name="ratio above 1")
    a = answers([q], NAMES, S, [4.0, 4.0])[0]
    # by hand: 60/-10 = -6 (no), 60/5 = 12 (yes)
    assert a.name == "ratio above 1" and a.expr == "V1.speed / (V2.speed - 50) > 1"
    assert a.probability == 0.5 and a.undefined == 2 and a.draws == 4
    assert a.standard_error == pytest.approx(math.sqrt(0.25 / 4))
    assert "undefined in 2 of 4 draws" in a.note and "division by zero" in a.note
    # negation and `or` keep the draw undefined (not a quiet True from `not False`)
    for expr in ("not V1.speed / (V2.speed - 50) > 1", "V1.speed / (V2.speed - 50) > 1 or V1.speed > 100"):
        b = parse_question(expr, NAMES).answer({"V1.speed": S[:, 0], "V2.speed": S[:, 1]})
        assert b.undefined == 2 and b.probability == 0.5, expr


def test_no_defined_draw_gives_nan_with_the_note_and_a_nan_sample_is_undefined():
    q = parse_question("V1.speed / (V2.speed - 50) > 1", NAMES)
    a = q.answer({"V1.speed": np.array([1.0, 2.0]), "V2.speed": np.array([50.0, 50.0])})
    assert math.isnan(a.probability) and math.isnan(a.standard_error) and a.undefined == 2 and a.note
    b = parse_question("V1.speed > 1", NAMES).answer({"V1.speed": np.array([np.nan, 2.0]),
                                                      "V2.speed": np.array([0.0, 0.0])})
    assert b.probability == 1.0 and b.undefined == 1


def test_defined_everywhere_has_no_note_and_the_name_defaults_to_the_expression():
    rng = np.random.default_rng(1)
    S = rng.uniform(0, 100, (500, 2))
    q = parse_question("V1.speed / (V2.speed + 1) > 1", NAMES)
    a = answers([q], NAMES, S, [500.0, 500.0])[0]
    assert a.name == a.expr == "V1.speed / (V2.speed + 1) > 1" and a.undefined == 0 and a.note == ""
    assert a.probability == pytest.approx(np.mean(S[:, 0] / (S[:, 1] + 1) > 1))
