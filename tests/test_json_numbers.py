"""crashlab.units.json_number, the one home of a JSON document's numbers (simulate/compare --json, an Outcome's,
a Monte Carlo's and a reconstruction's JSON): JSON has neither NaN nor inf, so they are null, as is anything that
is not a number; the rest rounded to 6 decimals unless asked otherwise."""
from __future__ import annotations

import json
import math

import numpy as np
import pytest

from crashlab.units import json_number


@pytest.mark.parametrize("value", [math.nan, math.inf, -math.inf, np.float64("nan"), None, "fast", [1.0]])
def test_what_json_cannot_hold_is_null(value):
    assert json_number(value) is None


def test_numbers_are_rounded_to_six_decimals_or_kept():
    assert json_number(1.23456789) == 1.234568
    assert json_number(np.float32(0.5)) == 0.5
    assert json_number(np.int64(3)) == 3.0
    assert json_number(1.23456789, None) == 1.23456789
    assert json_number(-2.0e-7) == -0.0
    # the document they make is strict JSON
    json.dumps([json_number(v) for v in (math.nan, 2.5, math.inf)], allow_nan=False)
