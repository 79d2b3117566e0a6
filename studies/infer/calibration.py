"""Calibration of `crashlab infer` (issue 14): does the 90 % interval of each variable hold the truth 90 % of the time?

    python studies/infer/calibration.py [--seeds 1-20] [--out DIR] [--importance SEED ...] [--noiseless]
    python studies/infer/calibration.py --prior [--seeds 1-20] [--out DIR]

Each seed runs calibration_twin.toml (the impulse model's run of side.toml's start plus Gaussian noise of
0.2 m and 5 deg on both rest poses; four free variables, flat priors) with noise_seed = infer.seed = seed, and
records per variable the 90 % interval and whether it holds the truth, and three diagnostics that separate a
wrong sampler or likelihood from a posterior that is right but lopsided:

- rank: the share of posterior samples more probable than the truth (log-likelihood above the truth's). With
  the right likelihood (the sigmas the noise was drawn with) and a sampler that samples it, this is close to
  uniform on [0, 1] over the seeds (for a Gaussian posterior exactly: 2 (max ln L - ln L(truth)) is chi2 with
  4 degrees of freedom, and the rank is its CDF); a too small sigma or a stuck sampler piles it up near 1.
- lin_z: where the linearised model puts the estimate: theta = truth - (J'J)^-1 J' r(truth), J the Jacobian
  of the normalised residuals at the truth (central differences, 0.1 in file units), in units of the linear
  standard deviation sqrt(diag (J'J)^-1). |z| <= 1.645 is a hit of an exact Gaussian posterior: the hits this
  noise draw would give if the model were linear.
- with --importance SEED: the posterior's 5/50/95 % quantiles by importance sampling (a Student-t proposal,
  4 degrees of freedom, twice emcee's covariance; 60,000 model evaluations) next to emcee's: a second,
  independent sampler.
- with --noiseless: the posterior of the twin without noise (its median against the truth: the lopsidedness
  of the posterior itself).

Writes DIR/calibration.csv (one row per seed and variable) and prints the hits per variable.

--prior: simulation-based calibration (Cook, Gelman & Rubin 2006; Talts et al. 2018). A Bayesian 90 % interval
holds its truth 90 % of the time on average over truths drawn from the prior the posterior uses, not at every
fixed truth. Seed k draws the truth of the four free variables from that prior, writes a copy of side.toml
carrying it (the study's base scene: the twin's evidence is that scene's run plus noise, noise_seed =
infer.seed = k) and samples the posterior. Per variable: the hit of the 90 % interval and the SBC rank (the
share of that variable's posterior samples below its truth), uniform on [0, 1] over the draws when the
posterior is right. The prior: flat within the [[free]] bounds, restricted to the starts the likelihood can
score (crashlab.reconstruction.infer: a start that overlaps, a run without contact or a vehicle still moving
at the end has likelihood 0, for every evidence). That restriction is part of the posterior's prior: the data
of such a start cannot come from the model the posterior assumes, so a draw there is redrawn (the next draw
of the same generator) and counted, never scored. The truth's generator is default_rng([14, k]), a stream of
its own: default_rng(k) also draws the noise and the walkers' starting points, and the truth must not share
their bits. Writes DIR/sbc.csv.

The numbers are in studies/infer/calibration.md.
"""
from __future__ import annotations

import argparse
import re
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from scipy import stats

from crashlab.reconstruction.infer import run_posterior
from crashlab.reconstruction.posterior import load_posterior

HERE = Path(__file__).resolve().parent
TWIN = HERE / "calibration_twin.toml"


def calibration_study(seed: int | None, directory, scene=None) -> Path:
    """calibration_twin.toml with noise_seed = infer.seed = seed (None: no noise) in `directory`; its base scene
    side.toml, or `scene` (a copy carrying another truth: --prior)."""
    side = Path(scene or HERE.parent / "pc_crash" / "side.toml").resolve().as_posix()
    text = TWIN.read_text().replace('"../pc_crash/side.toml"', f'"{side}"')
    if seed is None:
        text = re.sub(r"^noise_seed = .*\n", "", text, flags=re.M)
    else:
        text = re.sub(r"^noise_seed = .*$", f"noise_seed = {seed}", text, flags=re.M)
        text = re.sub(r"^seed = .*$", f"seed = {seed}", text, flags=re.M)
    path = Path(directory) / f"{'sbc' if scene else 'calibration'}_{'noiseless' if seed is None else seed}.toml"
    path.write_text(text)
    return path


SIDE = HERE.parent / "pc_crash" / "side.toml"
TRUTH_STREAM = 14  # default_rng([TRUTH_STREAM, seed]): the truth's own stream (module docstring)


def scene_with(values: dict, path) -> Path:
    """A copy of side.toml at `path` whose vehicles start with `values` ({"vehicles.V1.speed": 47.3, ...},
    file units; start-state quantities written in the vehicle's [[vehicles]] table), checked against
    crashlab.fields' setter: the copy's scene must equal fields.setter(side, paths)(values) in every
    vehicle's start state, else ValueError (so the copy means exactly what the posterior's fields mean)."""
    from crashlab import fields
    from crashlab.scene_file import load_scene
    lines = SIDE.read_text().splitlines(keepends=True)
    heads = [i for i, ln in enumerate(lines) if ln.strip() == "[[vehicles]]"]
    for p, v in values.items():
        f = fields.parse(p)
        if f.kind != "vehicle":
            raise ValueError(f"{p}: only a vehicle's start state is written into the scene copy")
        for a in heads:
            b = next((i for i in range(a + 1, len(lines)) if lines[i].lstrip().startswith("[")), len(lines))
            if any(re.match(rf'^name = "{re.escape(f.vehicle)}"\s*$', lines[i]) for i in range(a, b)):
                k = [i for i in range(a, b) if re.match(rf"^{f.quantity} = ", lines[i])]
                if len(k) != 1:
                    raise ValueError(f"{p}: {len(k)} lines '{f.quantity} = ' in {f.vehicle}'s table of {SIDE}")
                lines[k[0]] = f"{f.quantity} = {float(v)!r}\n"
                break
        else:
            raise ValueError(f"{p}: no vehicle {f.vehicle!r} in {SIDE}")
    path = Path(path)
    path.write_text("".join(lines))
    base = load_scene(SIDE)
    want = fields.setter(base, list(values))(list(values.values()))
    got = load_scene(path)
    def state(scene):
        return [(v.name, v.x, v.y, v.heading, v.speed, v.yaw_rate, v.steer) for v in scene.vehicles]
    if state(got) != state(want):
        raise ValueError(f"{path}: the scene copy differs from crashlab.fields' setter: {state(got)} != "
                         f"{state(want)}")
    return path


def prior_study(seed: int, directory, template=None):
    """Simulation-based calibration's run `seed` (module docstring, --prior): (study path, drawn truth in
    file units, redrawn: [(values, reason), ...] of the draws the likelihood cannot score)."""
    from crashlab.errors import InputError
    template = template or load_posterior(calibration_study(seed, directory))
    rng = np.random.default_rng([TRUTH_STREAM, seed])
    paths = [v.path for v in template.variables]
    redrawn = []
    while True:
        x = template.sample_prior(1, rng)[0]
        try:
            scene = scene_with(dict(zip(paths, x)), Path(directory) / f"sbc_scene_{seed}.toml")
            study = calibration_study(seed, directory, scene)
            post = load_posterior(study)
        except InputError as err:  # the scene's own run failed or left a vehicle moving; an overlapping start
            redrawn.append((x, str(err)))
            continue
        if not np.isfinite(post.log_likelihood(post.truth[None])[0]):
            redrawn.append((x, "likelihood 0 at the truth (overlap, no contact or not at rest)"))
            continue
        if np.max(np.abs(post.truth - x)) > 1e-9:
            raise ValueError(f"seed {seed}: the scene copy's truth {post.truth} is not the draw {x}")
        return post, redrawn


def sbc_run(seed: int, directory, template=None) -> dict:
    """One run of simulation-based calibration (module docstring): the drawn truth, the posterior's 5/50/95 %
    quantiles, the hits of the 90 % intervals, the SBC ranks, tau and ESS per variable, the truth's joint rank
    (truth_rank: a truth far more probable than the samples is a mode the walkers missed), the redrawn draws."""
    t0 = time.time()
    post, redrawn = prior_study(seed, directory, template)
    res = run_posterior(post, None, progress=False)
    lo, med, hi = res.interval()
    t = post.truth
    return dict(seed=seed, labels=post.labels, truth=t, lo=lo, med=med, hi=hi, hit=(lo <= t) & (t <= hi),
                rank=sbc_rank(res, t), joint=truth_rank(post, res), tau=res.tau, ess=res.ess, redrawn=redrawn,
                evaluations=res.evaluations, seconds=time.time() - t0, post=post, res=res)


def sbc_rank(res, truth) -> np.ndarray:
    """(d,) the share of each variable's posterior samples below its truth (Talts et al. 2018)."""
    return np.mean(res.samples < np.asarray(truth)[None, :], axis=0)


def clopper_pearson(k: int, n: int, level=0.95) -> tuple[float, float]:
    a = 1 - level
    lo = stats.beta.ppf(a / 2, k, n - k + 1) if k > 0 else 0.0
    hi = stats.beta.ppf(1 - a / 2, k + 1, n - k) if k < n else 1.0
    return float(lo), float(hi)


def residuals(post, X) -> np.ndarray:
    """(n, m) normalised residuals of rows X (file units)."""
    _, R = post.problem._simulate([post.setter(x) for x in np.atleast_2d(X)])
    return R


def jacobian(post, x, h=0.1) -> np.ndarray:
    """(m, d) d r / d theta at x by central differences [1 / file unit]."""
    E = np.eye(len(x)) * h
    R = residuals(post, np.concatenate([x + E, x - E]))
    return ((R[:len(x)] - R[len(x):]) / (2 * h)).T


def truth_rank(post, res) -> float:
    """Share of the posterior's samples with a log-likelihood above the truth's."""
    lt = post.log_likelihood(post.truth[None])[0]
    return float(np.mean(res.log_likelihood > lt))


def importance_quantiles(post, samples, n=60_000, seed=0, q=(0.05, 0.5, 0.95)):
    """(len(q), d) quantiles of the posterior by importance sampling (module docstring) and the ESS."""
    prop = stats.multivariate_t(samples.mean(0), 2.0 * np.cov(samples.T), df=4, seed=seed)
    X = prop.rvs(n)
    lw = post.log_posterior(X) - prop.logpdf(X)
    w = np.exp(lw - np.max(lw[np.isfinite(lw)]))
    w[~np.isfinite(w)] = 0.0
    out = np.empty((len(q), X.shape[1]))
    for j in range(X.shape[1]):
        i = np.argsort(X[:, j])
        c = np.cumsum(w[i])
        out[:, j] = np.interp(q, c / c[-1], X[i, j])
    return out, float(w.sum() ** 2 / np.sum(w ** 2))


def _seeds(text: str) -> list[int]:
    out = []
    for part in text.split(","):
        a, _, b = part.partition("-")
        out += list(range(int(a), int(b or a) + 1))
    return out


def main_prior(seeds, out_dir) -> int:
    """--prior: simulation-based calibration over `seeds`; writes sbc.csv, prints the hits, their binomial
    95 % intervals and the Kolmogorov-Smirnov p of each variable's ranks against uniform."""
    out = Path(out_dir or tempfile.mkdtemp(prefix="sbc_"))
    out.mkdir(parents=True, exist_ok=True)
    work = Path(tempfile.mkdtemp(prefix="sbc_studies_"))
    template = load_posterior(calibration_study(seeds[0], work))
    t_all = time.time()
    runs = []
    with open(out / "sbc.csv", "w") as fh:
        fh.write("seed,variable,truth,q05,median,q95,hit,rank,joint_rank,tau,ess,redrawn,seconds\n")
        for seed in seeds:
            r = sbc_run(seed, work, template)
            del r["post"], r["res"]  # (the chains: not kept over 100 runs)
            runs.append(r)
            for j, lab in enumerate(r["labels"]):
                vals = [f"{r[k][j]:.6g}" for k in ("truth", "lo", "med", "hi")] + [str(int(r["hit"][j]))]
                vals += [f"{r['rank'][j]:.6g}", f"{r['joint']:.6g}", f"{r['tau'][j]:.4g}", f"{r['ess'][j]:.4g}",
                         str(len(r["redrawn"])), f"{r['seconds']:.1f}"]
                fh.write(",".join([str(seed), lab] + vals) + "\n")
            fh.flush()
            for x, why in r["redrawn"]:
                print(f"seed {seed:3d}: redrawn {np.round(x, 2).tolist()}: {why}")
            print(f"seed {seed:3d}: " + ", ".join(
                f"{lab} {t:.2f} [{a:.2f} {m:.2f} {b:.2f}]{'' if h else '*'} r {q:.2f}"
                for lab, t, a, m, b, h, q in zip(r["labels"], r["truth"], r["lo"], r["med"], r["hi"], r["hit"],
                                                 r["rank"]))
                + f"; joint rank {r['joint']:.2f}; tau max {np.max(r['tau']):.1f}, ESS min {np.min(r['ess']):.0f}; "
                f"{r['seconds']:.0f} s", flush=True)
    labels = runs[0]["labels"]
    n = len(runs)
    hits = np.sum([r["hit"] for r in runs], axis=0)
    ranks = np.array([r["rank"] for r in runs])
    joint = [r["joint"] for r in runs]
    print(f"simulation-based calibration, {n} draws from the prior, {time.time() - t_all:.0f} s; "
          f"{sum(len(r['redrawn']) for r in runs)} draws redrawn (likelihood 0 at the truth) in "
          f"{sum(bool(r['redrawn']) for r in runs)} runs")
    for j, lab in enumerate(labels):
        a, b = clopper_pearson(int(hits[j]), n)
        print(f"  {lab:11s} hits {hits[j]:3d}/{n} = {hits[j] / n:.2f} (binomial 95 % {a:.2f}-{b:.2f}); "
              f"ranks KS p = {stats.kstest(ranks[:, j], 'uniform').pvalue:.2f}")
    print("joint rank of the truth (share of samples more probable): "
          f"KS p = {stats.kstest(joint, 'uniform').pvalue:.2f}")
    print(f"written {out / 'sbc.csv'}")
    return 0


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", default="1-20", help="noise seeds, e.g. 1-20 or 1,5,7-9 (default 1-20)")
    ap.add_argument("--out", default=None, help="directory for calibration.csv (default: a temporary one)")
    ap.add_argument("--importance", default="", help="seeds to check by importance sampling, e.g. 2,3")
    ap.add_argument("--noiseless", action="store_true", help="also the posterior of the noiseless twin")
    ap.add_argument("--prior", action="store_true", help="simulation-based calibration: each seed's truth "
                    "drawn from the prior (module docstring)")
    args = ap.parse_args(argv)
    seeds = _seeds(args.seeds)
    if args.prior:
        return main_prior(seeds, args.out)
    check = set(_seeds(args.importance)) if args.importance else set()
    out = Path(args.out or tempfile.mkdtemp(prefix="calibration_"))
    out.mkdir(parents=True, exist_ok=True)
    work = Path(tempfile.mkdtemp(prefix="calibration_studies_"))
    base = load_posterior(calibration_study(None, work))
    J = jacobian(base, base.truth)
    C = np.linalg.inv(J.T @ J)
    lin_sd = np.sqrt(np.diag(C))
    labels = base.labels
    print("linear standard deviations at the truth: " + ", ".join(f"{a} {s:.2f}" for a, s in zip(labels, lin_sd)))
    rows, ranks = [], []
    hits, lin_hits = np.zeros(len(labels), int), np.zeros(len(labels), int)
    for seed in seeds:
        t0 = time.time()
        post = load_posterior(calibration_study(seed, work))
        res = run_posterior(post, None, progress=False)
        lo, med, hi = res.interval()
        t = post.truth
        hit = (lo <= t) & (t <= hi)
        z = (-(C @ J.T @ residuals(post, t)[0])) / lin_sd
        rank = truth_rank(post, res)
        hits += hit
        lin_hits += np.abs(z) <= 1.645
        ranks.append(rank)
        for j, lab in enumerate(labels):
            rows.append((seed, lab, t[j], lo[j], med[j], hi[j], int(hit[j]), z[j], rank, res.tau[j], res.ess[j]))
        print(f"seed {seed:3d}: " + ", ".join(f"{lab} [{a:.2f} {m:.2f} {b:.2f}]{'' if h else '*'}"
                                             for lab, a, m, b, h in zip(labels, lo, med, hi, hit))
              + f"; rank {rank:.3f}; lin z {np.round(z, 2)}; tau {np.round(res.tau, 1)}; {time.time() - t0:.0f} s",
              flush=True)
        if seed in check:
            qi, ess = importance_quantiles(post, res.samples, seed=seed)
            for j, lab in enumerate(labels):
                print(f"      {lab}: importance sampling {np.round(qi[:, j], 2)} (ESS {ess:.0f}), "
                      f"emcee {np.round([lo[j], med[j], hi[j]], 2)}")
    with open(out / "calibration.csv", "w") as fh:
        fh.write("seed,variable,truth,q05,median,q95,hit,lin_z,rank,tau,ess\n")
        for r in rows:
            fh.write(",".join([str(r[0]), r[1]] + [f"{v:.6g}" for v in r[2:]]) + "\n")
    n = len(seeds)
    print(f"hits of the 90 % intervals in {n} seeds: " + ", ".join(f"{a} {h}" for a, h in zip(labels, hits)))
    print("hits an exact Gaussian posterior (linearised model) would give for these noise draws: "
          + ", ".join(f"{a} {h}" for a, h in zip(labels, lin_hits)))
    print(f"ranks of the truth (sorted): {np.round(np.sort(ranks), 2).tolist()}; "
          f"Kolmogorov-Smirnov against uniform: p = {stats.kstest(ranks, 'uniform').pvalue:.2f}")
    if args.noiseless:
        res = run_posterior(base, None, progress=False)
        lo, med, hi = res.interval()
        print("noiseless twin: median - truth " + ", ".join(
            f"{a} {m - t:+.2f} ({(m - t) / s:+.2f} linear sd)" for a, m, t, s in zip(labels, med, base.truth, lin_sd)))
    print(f"written {out / 'calibration.csv'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
