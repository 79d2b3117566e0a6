"""Damage as evidence (issue 24, item 3; [evidence.damage.<vehicle>], crashlab.reconstruction.evidence,
docs/physics.md §28): the residual of a measured crush profile in sigma units against an independent
computation (the CRASH3 integral by quadrature, the sigma by finite differences, the simulated energy from
the impact rows' dissipated energy and the struck structures), exact at the candidate's own mass when the mass changes,
a twin's profile scoring zero at the truth, a wrong profile moving the likelihood, and bad input one line
naming the key."""
from __future__ import annotations

import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from conftest import FREE_SPEEDS, assert_one_error_line, assert_refused_with_one_line

from crashlab import fields
from crashlab.damage import DamageEvidence, damage_residual
from crashlab.reconstruction import load_study
from crashlab.reconstruction.evidence import log_likelihood_of
from crashlab.registry import get_model

REPO = Path(__file__).resolve().parent.parent
SIDE = REPO / "studies" / "pc_crash" / "side.toml"
PROFILE = [0.10, 0.18, 0.25, 0.22, 0.15, 0.08]  # V1's front, m
WIDTH, SIGMA_C, SIGMA_S = 1.2, 0.02, 0.15


def damage(vehicle: str, side: str, width: float, extra: str = "") -> str:
    """An [evidence.damage.<vehicle>] table with the module's sigmas."""
    return (f'[evidence.damage.{vehicle}]\nside = "{side}"\nwidth = {width}\n{extra}'
            f"sigma_crush = {SIGMA_C}\nsigma_stiffness = {SIGMA_S}\n")


MEASURED = (f'\nscene = "{SIDE.as_posix()}"\n{FREE_SPEEDS}[evidence.rest.V1]\nx = 6.30\ny = -2.20\nsigma_xy = 1.0\n'
            + damage("V1", "front", WIDTH, f"profile = {PROFILE}\n"))
TWIN = (f'\nscene = "{SIDE.as_posix()}"\n{FREE_SPEEDS}[evidence]\ntwin = true\n[evidence.rest.V1]\nsigma_xy = 1.0\n'
        + damage("V1", "front", WIDTH) + damage("V2", "left", 1.5, "offset = 0.3\n"))


def write(tmp_path, text, name="study.toml") -> Path:
    path = tmp_path / name
    path.write_text(text)
    return path


# ------------------------------------------------------------------ independent reference
def crash3_energy(profile, width, A, B, scale=1.0) -> float:
    """J, the CRASH3 integral of (A C + B C^2 / 2 + A^2 / 2B) over the width, C linear between the equally
    spaced depths, by quadrature on a fine grid (stiffness A, B both times `scale`)."""
    A, B = A * scale, B * scale
    w = np.linspace(0.0, width, 20001)
    c = np.interp(w, np.linspace(0.0, width, len(profile)), profile)
    f = A * c + B * c * c / 2.0 + A * A / (2.0 * B)
    return float(np.sum((f[1:] + f[:-1]) / 2.0 * np.diff(w)))


def reference_ees_and_sigma(profile, width, A, B, mass) -> tuple[float, float]:
    """(EES, sigma) [km/h]: EES = sqrt(2 E / m); sigma by central finite differences of EES with respect to
    every depth (sigma_C each) and the stiffness scale (sigma_s), the errors independent."""
    def ees(p, scale=1.0):
        return math.sqrt(2.0 * crash3_energy(p, width, A, B, scale) / mass) * 3.6
    h = 1e-5
    var = 0.0
    for i in range(len(profile)):
        up, dn = list(profile), list(profile)
        up[i] += h
        dn[i] -= h
        var += ((ees(up) - ees(dn)) / (2 * h) * SIGMA_C) ** 2
    var += ((ees(profile, 1 + h) - ees(profile, 1 - h)) / (2 * h) * SIGMA_S) ** 2
    return ees(profile), math.sqrt(var)


STRUCK = {"V1": "front", "V2": "side"}  # side.toml: V1's front strikes V2's left side


def simulated_ees(outcome, name: str, scene) -> float:
    """km/h: the vehicle's share of every impact's dissipated energy summed, as an EES at its mass; the two struck
    structures in series carry the same force, so each takes the energy as its compliance 1/B (docs/physics.md
    §21), the sides STRUCK."""
    spec = {v.name: v.spec for v in scene.vehicles}
    e = 0.0
    for r in outcome.impact_rows:
        if r["vehicle"] == name:
            own = 1.0 / spec[name].structure[STRUCK[name]].B
            other = 1.0 / spec[r["other"]].structure[STRUCK[r["other"]]].B if r["other"] in spec else 0.0
            e += r["energy"] * own / (own + other)
    return math.sqrt(2.0 * e / spec[name].mass) * 3.6


# ------------------------------------------------------------------ the residual
def test_damage_residual_in_sigma_units_against_an_independent_computation(tmp_path):
    study = load_study(write(tmp_path, MEASURED))
    es = study.evidence_set
    assert [it.label for it in es.items] == ["rest.V1", "damage.V1"]
    assert es.labels[-1] == "damage.V1.ees" and study.objective_names == ["V1"]
    spec = study.scene.vehicle("V1").spec
    s = spec.structure["front"]
    ref, sigma = reference_ees_and_sigma(PROFILE, WIDTH, s.A, s.B, spec.mass)
    it = es.items[1]
    assert it.values[0] == pytest.approx(ref, rel=1e-6) and it.sigmas[0] == pytest.approx(sigma, rel=1e-4)
    problem = study.make_problem()
    X = np.array([[50.0, 30.0], [60.0, 30.0], [45.0, 20.0]])
    R = problem.evaluate(X, return_values_of=["residuals"])
    model = get_model("impulse")
    for k, scene in enumerate(problem.scenes_for(X)):
        o = model.simulate(scene)
        expected = (simulated_ees(o, "V1", scene) - ref) / sigma
        assert R[k, -1] == pytest.approx(expected, rel=1e-4, abs=1e-6), (X[k], R[k])
    print(f"\nEES from the damage {ref:.2f} ± {sigma:.2f} km/h; damage residuals {np.round(R[:, -1], 3)}")
    assert abs(R[1, -1]) > 1.0  # 10 km/h faster: a harder impact, more than a sigma


def test_the_residual_is_the_one_at_the_candidates_own_mass(tmp_path):
    """A changed mass (an uncertain parameter) changes both EES by 1/sqrt(m): the residual equals
    crashlab.damage.damage_residual with the candidate's own vehicle."""
    study = load_study(write(tmp_path, MEASURED))
    es = study.evidence_set
    base = fields.set_fields(study.scene, ["vehicles.V1.speed", "vehicles.V2.speed"], [55.0, 30.0])
    heavy = fields.set_field(base, "vehicles.V1.mass", 1400.0)
    model = get_model("impulse")
    o_base, o_heavy = model.simulate(base), model.simulate(heavy)
    evidence = DamageEvidence(side="front", profile=PROFILE, width=WIDTH, sigma_crush=SIGMA_C,
                              sigma_stiffness=SIGMA_S)
    for scene, o in ((base, o_base), (heavy, o_heavy)):
        own = damage_residual(simulated_ees(o, "V1", scene), evidence, scene.vehicle("V1").spec)
        assert es.residuals([o])[0, -1] == pytest.approx(own, rel=1e-6)
    assert es.residuals([o_heavy])[0, -1] != pytest.approx(es.residuals([o_base])[0, -1], abs=0.05)


def test_a_wrong_profile_moves_the_likelihood_and_a_miss_cannot_be_scored(tmp_path):
    right = load_study(write(tmp_path, MEASURED))
    deeper = [c + 0.10 for c in PROFILE]
    wrong = load_study(write(tmp_path, MEASURED.replace(str(PROFILE), str(deeper)), "wrong.toml"))
    scene = fields.set_fields(right.scene, ["vehicles.V1.speed", "vehicles.V2.speed"], [50.0, 30.0])
    o = get_model("impulse").simulate(scene)
    r_right, r_wrong = right.evidence_set.residuals([o])[0], wrong.evidence_set.residuals([o])[0]
    np.testing.assert_allclose(r_right[:2], r_wrong[:2])  # the rest pose's residuals do not change
    assert wrong.evidence_set.items[1].values[0] > right.evidence_set.items[1].values[0] + 3.0  # km/h
    L_right, L_wrong = log_likelihood_of(r_right[None])[0], log_likelihood_of(r_wrong[None])[0]
    assert L_right - L_wrong == pytest.approx(0.5 * (r_wrong[-1] ** 2 - r_right[-1] ** 2), rel=1e-9)
    assert abs(L_right - L_wrong) > 0.5
    miss = fields.set_field(scene, "vehicles.V2.x", 30.0)  # V2 passes far ahead of V1: no impact row
    o_miss = get_model("impulse").simulate(miss)
    assert not o_miss.impact_rows
    assert np.isnan(right.evidence_set.residuals([o_miss])).all()


def test_damage_on_a_side_no_impact_struck_cannot_be_scored(tmp_path):
    """The damage says where the vehicle was struck: a candidate whose impacts strike it elsewhere has no energy on
    that side to compare (docs/physics.md §21): NaN residuals, log-likelihood -inf; the same profile on the side
    the impact strikes is scored (V1's front hits V2's left side)."""
    scene = fields.set_fields(load_study(write(tmp_path, MEASURED)).scene, ["vehicles.V1.speed", "vehicles.V2.speed"],
                              [50.0, 30.0])
    o = get_model("impulse").simulate(scene)
    assert {(r["vehicle"], r["side"]) for r in o.impact_rows} == {("V1", "front"), ("V2", "left")}
    rear = load_study(write(tmp_path, MEASURED.replace('side = "front"', 'side = "rear"'), "rear.toml"))
    R = rear.evidence_set.residuals([o])
    assert np.isnan(R).all() and log_likelihood_of(R)[0] == -math.inf
    front = load_study(write(tmp_path, MEASURED))
    assert np.isfinite(front.evidence_set.residuals([o])).all()


@pytest.mark.parametrize("model_name", ["impulse", "pymunk", "multibody"])
def test_damage_on_the_other_flank_cannot_be_scored(tmp_path, model_name):
    """Both flanks have the side structure, but the damage says which one was struck: V1's front strikes V2's left
    flank, so damage measured on V2's right flank has no simulated energy to compare (NaN residual, log-likelihood
    -inf; before, both flanks were one "side" and it was scored against the left-flank impact), the same damage on
    the left flank is scored. In every model that finds its own contact."""
    scene = fields.set_fields(load_study(write(tmp_path, MEASURED)).scene, ["vehicles.V1.speed", "vehicles.V2.speed"],
                              [50.0, 30.0])
    o = get_model(model_name).simulate(scene)
    assert ("V2", "left") in {(r["vehicle"], r["side"]) for r in o.impact_rows}
    assert ("V2", "right") not in {(r["vehicle"], r["side"]) for r in o.impact_rows}
    flank = damage("V2", "{flank}", 1.5, "offset = 0.3\nprofile = [0.1, 0.2, 0.25, 0.2, 0.1, 0.05]\n")
    for side, scored in (("right", False), ("left", True)):
        study = load_study(write(tmp_path, MEASURED + flank.replace("{flank}", side), f"{side}.toml"))
        R = study.evidence_set.residuals([o])[0]
        assert np.isfinite(R[-1]) == scored, side      # V2's damage is the last residual


def test_damage_evidence_names_its_flank(tmp_path):
    text = MEASURED + damage("V2", "side", 1.5, "profile = [0.1, 0.2]\n")
    assert_refused_with_one_line(load_study, write(tmp_path, text), "evidence.damage.V2.side",
                                 ["left or right"])


def test_a_twin_without_an_impact_on_the_damaged_side_is_refused(tmp_path):
    text = TWIN.replace('side = "front"', 'side = "rear"')
    assert_refused_with_one_line(load_study, write(tmp_path, text), "evidence.damage.V1",
                                 ["no impact of V1 on its rear"])


def test_twin_fills_the_profiles_and_scores_zero_at_the_truth(tmp_path):
    study = load_study(write(tmp_path, TWIN))
    items = {it.label: it for it in study.evidence_set.items}
    assert set(items) == {"rest.V1", "damage.V1", "damage.V2"}
    assert "front crush" in items["damage.V1"].detail and "left crush" in items["damage.V2"].detail
    problem = study.make_problem()
    truth = problem.base_values()
    R = problem.evaluate(np.array([truth, truth + [8.0, 0.0]]), return_values_of=["residuals"])
    np.testing.assert_allclose(R[0], 0.0, atol=1e-9)
    assert np.all(np.abs(R[1, -2:]) > 0.5)
    # the damage is in the evidence list of summary.md
    assert any(line.startswith("damage.V2: ees = ") for line in study.evidence_set.describe())
    noisy = load_study(write(tmp_path, TWIN.replace("twin = true", "twin = true\nnoise_seed = 2"), "noisy.toml"))
    assert noisy.evidence_set.items[1].values != study.evidence_set.items[1].values


# ------------------------------------------------------------------ bad input
BAD = {  # id: (file, old, new, key, words)
    "no-profile": (MEASURED, f"profile = {PROFILE}\n", "", "evidence.damage.V1.profile", ["missing"]),
    "profile-in-twin": (TWIN, "side = \"front\"\n", "side = \"front\"\nprofile = [0.1, 0.1]\n",
                        "evidence.damage.V1.profile", ["twin"]),
    "wide": (MEASURED, f"width = {WIDTH}", "width = 2.5", "evidence.damage.V1.width", ["structure width"]),
    "negative-depth": (MEASURED, "0.25", "-0.25", "evidence.damage.V1.profile[3]", ["negative"]),
    "five-depths": (MEASURED, "0.1, 0.18,", "0.18,", "evidence.damage.V1.profile", ["2, 4 or 6"]),
    "side": (MEASURED, 'side = "front"', 'side = "roof"', "evidence.damage.V1.side", ["front"]),
    "vehicle": (MEASURED, "[evidence.damage.V1]", "[evidence.damage.V5]", "evidence.damage.V5", ["'V5'"]),
    "sigma": (MEASURED, f"sigma_crush = {SIGMA_C}", "sigma_crush = 0.0", "evidence.damage.V1.sigma_crush",
              ["greater than 0"]),
    "unknown-key": (MEASURED, "side = \"front\"", "side = \"front\"\nstiffness = 3", "evidence.damage.V1.stiffness",
                    []),
    "pdof-pulls": (MEASURED, "side = \"front\"", "side = \"front\"\npdof = 120.0", "evidence.damage.V1.pdof",
                   ["cannot have crushed"]),
}


@pytest.mark.parametrize("case", list(BAD), ids=list(BAD))
def test_bad_damage_evidence_is_one_error_naming_the_key(tmp_path, case):
    text, old, new, key, words = BAD[case]
    assert old in text
    assert_refused_with_one_line(load_study, write(tmp_path, text.replace(old, new, 1)), key, words)


def test_bad_damage_evidence_on_the_command_line_exits_2(tmp_path):
    path = write(tmp_path, MEASURED.replace(f"width = {WIDTH}", "width = 2.5"))
    for command in ("reconstruct", "infer"):
        res = subprocess.run([sys.executable, "-m", "crashlab.cli", command, str(path), "--no-progress"]
                             + (["--out", str(tmp_path / "out")] if command == "infer" else []),
                             capture_output=True, text=True, timeout=300)
        assert_one_error_line(res, path, "evidence.damage.V1.width", ["structure width"])


@pytest.mark.parametrize("zero", [[0.0] * 4, [0.001] * 4])
def test_a_profile_without_residual_crush_is_scored_as_an_upper_bound(tmp_path, zero):
    """All depths 0 (or 1 mm, within the 20 mm measurement's sigma of none): the CRASH3 energy, about G L (the most
    the front absorbs without residual crush), bounds the EES from above; a run below it is no misfit, one above it
    scores only its excess (the bound written here from A, B and the width, independent of crashlab.damage).
    Before, it was scored as a measurement: a light touch counted several sigma below."""
    text = MEASURED.replace(f"profile = {PROFILE}", f"profile = {zero}")
    study = load_study(write(tmp_path, text))
    it = study.evidence_set.items[1]
    spec = study.scene.vehicle("V1").spec
    s = spec.structure["front"]
    c = zero[0]
    bound = math.sqrt(2.0 * (s.A * c + s.B * c * c / 2 + s.A ** 2 / (2.0 * s.B)) * WIDTH / spec.mass) * 3.6
    assert it.upper_bound and it.values[0] == pytest.approx(bound, rel=1e-9)
    assert "damage.V1: ees <= " in study.evidence_set.describe()[1]
    assert not any("first order" in w for w in it.warnings)  # the first-order note needs a crush to compare with
    problem = study.make_problem()
    X = np.array([[8.0, 0.0], [50.0, 30.0]])  # a light touch, a hard impact
    R = problem.evaluate(X, return_values_of=["residuals"])
    model = get_model("impulse")
    sims = [simulated_ees(model.simulate(sc), "V1", sc) for sc in problem.scenes_for(X)]
    assert sims[0] < bound < sims[1]
    assert R[0, -1] == 0.0
    assert R[1, -1] == pytest.approx((sims[1] - bound) / it.sigmas[0], rel=1e-4)
    evidence = DamageEvidence(side="front", profile=zero, width=WIDTH, sigma_crush=SIGMA_C, sigma_stiffness=SIGMA_S)
    assert damage_residual(sims[0], evidence, spec) == 0.0
    assert damage_residual(sims[1], evidence, spec) == pytest.approx(R[1, -1], rel=1e-6)
