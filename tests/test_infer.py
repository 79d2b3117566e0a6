"""The posterior (issue 14, item 3; crashlab.reconstruction.infer): a twin's likelihood peaks at its truth, a
small posterior writes its files and its 90 % intervals hold the truth, questions parse and give the share of
samples where they hold, a resumed chain equals an uninterrupted one, and bad input is one line naming the
file and key. The slow calibration tests (one 20-seed run of studies/infer/calibration_twin.toml): the truth's
rank among the posterior samples is uniform over the seeds, and 90 % intervals hold the truth in 16-20 of 20
(at side.toml's fixed truth: an expected failure; with truths drawn from the prior, simulation-based
calibration, each speed's interval holds its truth 16-20 times and each variable's rank is uniform)."""
from __future__ import annotations

import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from conftest import FREE_SPEEDS, assert_one_error_line

from crashlab.errors import InputError
from crashlab.reconstruction.infer import run_posterior
from crashlab.reconstruction.posterior import load_posterior
from crashlab.reconstruction.questions import parse_question

REPO = Path(__file__).resolve().parent.parent
TWIN = REPO / "studies" / "infer" / "twin_infer.toml"
SIDE = REPO / "studies" / "pc_crash" / "side.toml"

SMALL = {"walkers": 16, "burn": 60, "samples": 16 * 60, "draws_plotted": 3}


def _study(tmp_path: Path, body: str, name="study.toml") -> Path:
    p = tmp_path / name
    p.write_text(f'scene = "{SIDE}"\nmodel = "impulse"\n' + body)
    return p


TWO_SPEEDS = "\n" + FREE_SPEEDS + """
[evidence]
twin = true
{noise}
[evidence.rest.V1]
sigma_xy = 0.2
sigma_heading = 5.0

[evidence.rest.V2]
sigma_xy = 0.2
sigma_heading = 5.0
"""


def _small(post, **kw):
    post.settings = post.settings.model_copy(update={**SMALL, **kw})
    return post


# ------------------------------------------------------------------ likelihood
def test_a_noiseless_twin_has_likelihood_one_at_its_truth_and_less_away(tmp_path):
    """Evidence = the model's run of the truth: every residual is 0 there (log-likelihood 0, exactly up to
    round-off), and 2 km/h off in V1's speed moves the rest poses, so the log-likelihood drops."""
    post = load_posterior(_study(tmp_path, TWO_SPEEDS.format(noise="")))
    truth = post.truth
    np.testing.assert_allclose(truth, [50.0, 30.0])
    L = post.log_likelihood(np.array([truth, truth + [2.0, 0.0], truth - [0.0, 3.0]]))
    assert abs(L[0]) < 1e-9
    assert L[1] < -0.5 and L[2] < -0.5
    # outside the bounds the prior is 0; a start whose outlines overlap is no collision of the scene
    assert post.log_posterior(np.array([[80.0, 30.0]]))[0] == -np.inf


def test_overlapping_start_has_zero_likelihood(tmp_path):
    body = TWO_SPEEDS.format(noise="").replace('field = "speed"\nlower = 10.0\nupper = 50.0',
                                                'field = "x"\nlower = 0.0\nupper = 5.0')
    post = load_posterior(_study(tmp_path, body))
    L = post.log_likelihood(np.array([[50.0, 3.5], [50.0, 0.5]]))  # V2 at V1's place: outlines overlap
    assert np.isfinite(L[0]) and L[1] == -np.inf


# ------------------------------------------------------------------ a small posterior end to end
def test_small_posterior_writes_its_files_and_holds_the_truth(tmp_path):
    post = _small(load_posterior(TWIN))
    out = tmp_path / "out"
    res = run_posterior(post, out, progress=False)
    df = pd.read_csv(out / "posterior.csv")
    assert list(df.columns) == ["V1.speed", "V2.speed", "road.friction", "log_likelihood"]
    assert len(df) == 16 * 60
    assert np.isfinite(df.to_numpy()).all() and (df["log_likelihood"] <= 0).all()
    lo, hi = df.quantile(0.05), df.quantile(0.95)
    for v, truth in (("V1.speed", 50.0), ("V2.speed", 30.0)):
        assert lo[v] <= truth <= hi[v], (v, lo[v], hi[v])
        assert hi[v] - lo[v] < 10.0  # the evidence narrows the 40 km/h prior range
    # the uncertain friction stays within its prior's support
    assert df["road.friction"].between(0.6, 1.0).all()
    text = (out / "summary.md").read_text()
    for word in ("V1.speed", "90 %", "ESS", "`V1.speed > 50`", "truth (twin)"):
        assert word in text
    p = float(next(line for line in text.splitlines() if "`V1.speed > 50`" in line).split("|")[2])
    assert p == pytest.approx(np.mean(df["V1.speed"] > 50), abs=1e-3)
    assert (out / "corner.png").stat().st_size > 1000 and (out / "posterior_top_view.png").stat().st_size > 1000
    assert res.evaluations >= len(df)


def test_resume_continues_the_same_chain(tmp_path):
    """A run stopped after 40 iterations and resumed gives the chain of an uninterrupted run, bit for bit."""
    settings = dict(walkers=12, burn=20, samples=12 * 40, checkpoint_every=20, draws_plotted=0)
    full = run_posterior(_small(load_posterior(TWIN), **settings), tmp_path / "a", progress=False)
    assert run_posterior(_small(load_posterior(TWIN), **settings), tmp_path / "b", progress=False,
                         stop_after=40) is None
    resumed = run_posterior(_small(load_posterior(TWIN), **settings), tmp_path / "b", resume=True,
                            progress=False)
    assert np.array_equal(full.chain, resumed.chain)
    assert (tmp_path / "a" / "posterior.csv").read_bytes() == (tmp_path / "b" / "posterior.csv").read_bytes()


def test_thinning_keeps_the_samples_asked_for(tmp_path):
    """`samples` are the kept ones: thin = 3 keeps 48 of 48 asked (every third of 3 x 6 iterations of 8 walkers);
    before, thinning divided them (16 kept) without a word (a fuzzer: thin = 100 kept 8 of 16)."""
    res = run_posterior(_small(load_posterior(TWIN), walkers=8, burn=2, samples=48, thin=3, draws_plotted=0),
                        progress=False)
    assert len(res.samples) == 48 and len(res.chain) == 2 + 18


def test_resume_refuses_a_changed_study(tmp_path):
    study = _study(tmp_path, TWO_SPEEDS.format(noise="noise_seed = 1") + "\n[infer]\nwalkers = 8\nburn = 4\n"
                   "samples = 80\ncheckpoint_every = 2\ndraws_plotted = 0\n")
    run_posterior(load_posterior(study), tmp_path / "o", progress=False, stop_after=2)
    study.write_text(study.read_text().replace("noise_seed = 1", "noise_seed = 2"))
    with pytest.raises(InputError, match=r"infer_checkpoint.pkl: --resume: .*different study \(.*evidence"):
        run_posterior(load_posterior(study), tmp_path / "o", resume=True, progress=False)


# ------------------------------------------------------------------ questions
def test_questions_give_the_share_of_samples_where_they_hold():
    names = ["V1.speed", "V2.speed", "V1.actions.0.t", "road.friction"]
    rng = np.random.default_rng(0)
    cols = {n: rng.uniform(0, 100, 1000) for n in names}
    v1, v2 = cols["V1.speed"], cols["V2.speed"]
    cases = {
        "V1.speed > 50": v1 > 50,
        "V1.speed>50 and V2.speed <= 20 or not V1.speed < 90": ((v1 > 50) & (v2 <= 20)) | ~(v1 < 90),
        "V1.speed > 50 and (V2.speed <= 20 or V2.speed > 80)": (v1 > 50) & ((v2 <= 20) | (v2 > 80)),
        "40 < V1.speed <= 60": (40 < v1) & (v1 <= 60),
        "V1.speed - 2 * V2.speed > -1.5e1": v1 - 2 * v2 > -15,
        "V1.actions.0.t < 50 and road.friction != 3": (cols["V1.actions.0.t"] < 50) & (cols["road.friction"] != 3),
        "-V1.speed / 2 >= -.5 * V2.speed": -v1 / 2 >= -0.5 * v2,
    }
    for expr, want in cases.items():
        q = parse_question(expr, names)
        assert q.probability(cols) == pytest.approx(np.mean(want)), expr
    assert parse_question("V1.speed > 50 and V2.speed < 1", names).names == ("V1.speed", "V2.speed")


@pytest.mark.parametrize("expr, words", [
    ("V3.speed > 50", ["unknown name 'V3.speed'", "V1.speed"]),
    ("V1.speed", ["not a comparison"]),
    ("V1.speed > 50 and", ["does not parse"]),
    ("__import__('os').system('true')", ["does not parse"]),
    ("V1.speed > 50 or 3", ["'or' needs comparisons"]),
    ("(V1.speed > 50", ["does not parse", "never closed"]),
    ("V1.speed.real > 50", ["unknown name 'V1.speed.real'"]),
    ("V1.speed > 50 if True else False", ["IfExp is not allowed"]),
    ("V1.speed ** 2 > 50", ["** is not allowed"]),
    ("V1.speed > 'x'", ["Constant is not allowed"]),
    ("V1.speed >> 50", ["does not parse", ">> is not allowed"]),
])
def test_bad_questions_are_refused(expr, words):
    with pytest.raises(InputError) as err:
        parse_question(expr, ["V1.speed", "V2.speed"], "s.toml", "questions.2.expr")
    assert str(err.value).startswith("s.toml: questions.2.expr: ")
    for w in words:
        assert w in str(err.value)


def _cli(study, out):
    return subprocess.run([sys.executable, "-m", "crashlab.cli", "infer", str(study), "--out", str(out),
                           "--no-progress"], capture_output=True, text=True, timeout=120)


def test_a_question_that_does_not_parse_is_one_line_exit_2(tmp_path):
    study = _study(tmp_path, TWO_SPEEDS.format(noise="") + '\n[[questions]]\nexpr = "V1.speed > 50"\n'
                   '\n[[questions]]\nexpr = "V1.speed > 50 and import os"\n')
    assert_one_error_line(_cli(study, tmp_path / "o"), study, "questions.1.expr", ["does not parse"])


def test_bad_infer_and_uncertain_input_is_one_line_exit_2(tmp_path):
    study = _study(tmp_path, TWO_SPEEDS.format(noise="") + "\n[infer]\nwalkers = 3\n", "a.toml")
    assert_one_error_line(_cli(study, tmp_path / "o"), study, "infer.walkers")
    # an odd number of walkers was run as the next even one without a word (a fuzzer): refused
    study = _study(tmp_path, TWO_SPEEDS.format(noise="") + "\n[infer]\nwalkers = 9\n", "w.toml")
    assert_one_error_line(_cli(study, tmp_path / "o"), study, "infer.walkers", ["multiple of 2"])
    study = _study(tmp_path, TWO_SPEEDS.format(noise="") + '\n[[uncertain]]\nfield = "road.frictionn"\n'
                   'distribution = "uniform"\nlower = 0.5\nupper = 0.9\n', "b.toml")
    assert_one_error_line(_cli(study, tmp_path / "o"), study, "uncertain.0.field")
    study = _study(tmp_path, TWO_SPEEDS.format(noise="").replace("sigma_xy = 0.2\n", "", 1), "c.toml")
    assert_one_error_line(_cli(study, tmp_path / "o"), study, "evidence.rest.V1.sigma_xy")


# ------------------------------------------------------------------ calibration (slow)
def _calibration_script():
    """studies/infer/calibration.py as a module (its study writer and the truth's rank)."""
    import importlib.util
    spec = importlib.util.spec_from_file_location("infer_calibration", REPO / "studies" / "infer" / "calibration.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


@pytest.fixture(scope="module")
def calibration_runs(tmp_path_factory):
    """Issue 14's calibration experiment, run once for the tests below: studies/infer/calibration_twin.toml
    (evidence = the impulse model's run of side.toml's start plus Gaussian noise, 0.2 m and 5 deg on both rest
    poses; four free variables: speeds and headings) for noise seeds 1-20. Per seed: the hits of the 90 %
    intervals (per variable) and the truth's rank (the share of posterior samples more probable than it)."""
    cal = _calibration_script()
    work = tmp_path_factory.mktemp("calibration")
    hits, ranks, labels = [], [], None
    t0 = time.time()
    for seed in range(1, 21):
        post = load_posterior(cal.calibration_study(seed, work))
        res = run_posterior(post, None, progress=False)
        lo, _, hi = res.interval()
        hits.append((lo <= post.truth) & (post.truth <= hi))
        ranks.append(cal.truth_rank(post, res))
        labels = res.labels
        print(f"seed {seed}: " + ", ".join(f"{lab} [{a:.2f}, {b:.2f}]" for lab, a, b in zip(res.labels, lo, hi))
              + f"; rank of the truth {ranks[-1]:.3f}; ESS min {res.ess.min():.0f}, {res.evaluations} evaluations")
    hits = np.array(hits)
    print(f"hits per variable {dict(zip(labels, hits.sum(0).tolist()))}, {time.time() - t0:.0f} s")
    return labels, hits, np.array(ranks)


@pytest.mark.slow
def test_calibration_the_truth_ranks_uniformly_among_the_posterior_samples(calibration_runs):
    """The joint calibration of the same 20 runs: the share of posterior samples more probable than the truth
    is uniform on [0, 1] over the seeds when the likelihood has the sigmas the noise was drawn with and the
    sampler samples it (for a Gaussian posterior it is the chi2(4) CDF of 2 (max ln L - ln L(truth))); a too
    small sigma, noise on the wrong quantity or walkers stuck away from the truth pile it up near 1, a too
    large sigma near 0. Kolmogorov-Smirnov against uniform at the 1 % level (measured 2026-11-24: p = 0.54)."""
    from scipy import stats
    _, _, ranks = calibration_runs
    p = stats.kstest(ranks, "uniform").pvalue
    print(f"ranks {np.round(np.sort(ranks), 2).tolist()}, KS p = {p:.2f}")
    assert p > 0.01, (p, ranks)


@pytest.mark.slow
@pytest.mark.xfail(strict=True, reason="measured 2026-11-24: V2's speed interval holds the truth in 14 of 20 (V1 16, "
                   "headings 15/17). Sampler and likelihood check out (ranks uniform; importance sampling gives the "
                   "same quantiles); the flat-prior posterior of this nonlinear model is lopsided (noiseless median "
                   "V1 -0.3, V2 +0.4 linear sd) and these 20 noise draws would give only 16/16 even for a linear "
                   "model; over 100 seeds V1 86, V2 83: studies/infer/calibration.md")
def test_calibration_90_percent_intervals_hold_the_truth_16_to_20_times_in_20(calibration_runs):
    """Issue 14's calibration: evidence = the impulse model's run of a known start (side.toml) plus Gaussian
    noise (0.2 m, 5 deg on the rest poses), 20 noise seeds, four free variables (speeds, headings): the 90 %
    interval of each speed holds the truth in 16-20 of the 20 runs (binomial(20, 0.9): 16-20 has probability
    0.96)."""
    labels, hits, _ = calibration_runs
    n = hits.sum(0)
    assert labels[:2] == ["V1.speed", "V2.speed"]
    assert 16 <= n[0] <= 20 and 16 <= n[1] <= 20, dict(zip(labels, n.tolist()))


@pytest.fixture(scope="module")
def sbc_runs(tmp_path_factory):
    """Simulation-based calibration (Talts et al. 2018) of the same twin, run once for the test below: for
    seeds 1-20 the four free variables' truth is drawn from the posterior's prior (flat within the [[free]]
    bounds, where the likelihood can score a start), a copy of side.toml carries it, and the posterior is
    sampled from its noisy twin (calibration.py --prior). Per seed: the hits of the 90 % intervals and each
    variable's rank (the share of its posterior samples below its truth)."""
    cal = _calibration_script()
    work = tmp_path_factory.mktemp("sbc")
    template = load_posterior(cal.calibration_study(1, work))
    runs = []
    for seed in range(1, 21):
        r = cal.sbc_run(seed, work, template)
        runs.append(r)
        print(f"seed {seed}: " + ", ".join(f"{lab} {t:.2f} [{a:.2f}, {b:.2f}] rank {q:.2f}" for lab, t, a, b, q in
                                           zip(r["labels"], r["truth"], r["lo"], r["hi"], r["rank"]))
              + f"; {len(r['redrawn'])} redrawn")
    return runs[0]["labels"], np.array([r["hit"] for r in runs]), np.array([r["rank"] for r in runs])


@pytest.mark.slow
def test_sbc_90_percent_intervals_hold_prior_drawn_truths_16_to_20_times_and_ranks_are_uniform(sbc_runs):
    """Issue 14's calibration in its sound form (simulation-based calibration; Cook, Gelman & Rubin 2006): a
    Bayesian 90 % interval holds a truth drawn from its own prior with probability exactly 0.9, so each
    speed's interval holds its truth in 16-20 of the 20 runs (binomial(20, 0.9): probability 0.96), and
    each variable's rank of the truth among its posterior samples is uniform on [0, 1] (Kolmogorov-Smirnov
    at the 1 % level). A wrong likelihood (sigma, noise), a wrong prior or a sampler that misses part of
    the posterior fails it. Measured 2026-11-24 (studies/infer/calibration.md): hits V1.speed 16, V2.speed 16
    (headings 16, 18), rank KS p 0.016, 0.50, 0.31, 0.92; seeds 1-100: 89, 89, 85, 89 of 100. The run is
    seeded (the same numbers each time); a calibrated posterior passes a fresh set of 20 draws with
    probability about 0.88 (both speeds >= 16: 0.92; four KS tests at 1 %)."""
    from scipy import stats
    labels, hits, ranks = sbc_runs
    n = hits.sum(0)
    p = [stats.kstest(ranks[:, j], "uniform").pvalue for j in range(len(labels))]
    print(f"hits {dict(zip(labels, n.tolist()))}, rank KS p {dict(zip(labels, np.round(p, 3).tolist()))}")
    assert labels[:2] == ["V1.speed", "V2.speed"]
    assert 16 <= n[0] <= 20 and 16 <= n[1] <= 20, dict(zip(labels, n.tolist()))
    assert min(p) > 0.01, dict(zip(labels, p))


@pytest.mark.slow
def test_point_of_impact_and_edr_speed_narrow_v1_speed_threefold():
    """Issue 14's "evidence pays": on the eight-variable twin (plus two uncertain parameters) the point of
    impact and V1's EDR speed narrow the 90 % interval of V1's speed at least threefold against rest poses
    alone (the same noisy rest poses: noise_seed 1 in both files)."""
    width = {}
    for name in ("twin_infer8_rest.toml", "twin_infer8.toml"):
        post = load_posterior(REPO / "studies" / "infer" / name)
        res = run_posterior(post, None, progress=False)
        lo, _, hi = res.interval()
        j = res.labels.index("V1.speed")
        assert lo[j] <= 50.0 <= hi[j]
        width[name] = hi[j] - lo[j]
    print(width)
    assert width["twin_infer8_rest.toml"] >= 3.0 * width["twin_infer8.toml"], width
