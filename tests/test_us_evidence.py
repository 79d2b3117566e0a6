"""US customary units in the evidence lines of summary.md (issue 26 item 4; EvidenceSet.describe(system)): with
`--units us` every measured value and sigma is in ft or mph, named so; degrees as they are.

The expected lines are written here from the study's SI numbers with the exact definitions (1 ft = 0.3048 m,
1 mile = 1609.344 m; NIST SP 811), independent of the pint conversion the code uses."""
from __future__ import annotations

import re

import pytest
from test_us_studies import SI, SIDE, STUDY

from crashlab.reconstruction import load_study

FT, MPH = 0.3048, 1.609344  # m, km/h per US unit (exact by definition)


@pytest.fixture(scope="module")
def study(tmp_path_factory):
    path = tmp_path_factory.mktemp("us_evidence") / "si.toml"
    path.write_text(STUDY.format(units="", scene=SIDE.as_posix(), **{k: repr(v) for k, v in SI.items()}))
    return load_study(path)


def test_the_evidence_lines_in_us_units(study):
    s = SI
    us = study.evidence_set.describe("us")
    assert us == [
        f"rest.V1: x = {s['r1x'] / FT:.2f} ± {s['sxy'] / FT:.3g} ft, y = {s['r1y'] / FT:.2f} ± {s['sxy'] / FT:.3g} "
        "ft, heading = 26.00 ± 5 deg",
        f"rest.V2: x = {s['r2x'] / FT:.2f} ± {s['sxy'] / FT:.3g} ft, y = {s['r2y'] / FT:.2f} ± {s['sxy'] / FT:.3g} ft",
        f"impact: x = {s['ix'] / FT:.2f} ± {s['isig'] / FT:.3g} ft, y = {s['iy'] / FT:.2f} ± {s['isig'] / FT:.3g} ft",
        f"marks.0: V1's CG path within {s['msig'] / FT:g} ft of ({s['m0'] / FT:.2f}, 0.00), ({s['m1'] / FT:.2f}, "
        f"{s['m2'] / FT:.2f}) ft",
        f"edr.V1: speed_at_impact = {s['edr'] / MPH:.2f} ± {s['edrs'] / MPH:.3g} mph"]
    si = study.evidence_set.describe()
    assert si[0] == (f"rest.V1: x = {s['r1x']:.2f} ± {s['sxy']:.3g} m, y = {s['r1y']:.2f} ± {s['sxy']:.3g} m, "
                     "heading = 26.00 ± 5 deg")
    assert not any(re.search(r"\bm\b|km/h", line) for line in us)
