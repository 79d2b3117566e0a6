"""Calibration of `crashlab infer` (issue 14): does the 90 % interval of each variable hold the truth 90 % of the time?

    python studies/infer/calibration.py [--seeds 1-20] [--out DIR] [--importance SEED ...] [--noiseless]

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

Writes DIR/calibration.csv (one row per seed and variable) and prints the hits per variable. The numbers are
in studies/infer/calibration.md.
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

from crashlab.reconstruction.infer import load_posterior, run_posterior

HERE = Path(__file__).resolve().parent
TWIN = HERE / "calibration_twin.toml"


def calibration_study(seed: int | None, directory) -> Path:
    """calibration_twin.toml with noise_seed = infer.seed = seed (None: no noise) in `directory`."""
    side = (HERE.parent / "pc_crash" / "side.toml").as_posix()
    text = TWIN.read_text().replace('"../pc_crash/side.toml"', f'"{side}"')
    if seed is None:
        text = re.sub(r"^noise_seed = .*\n", "", text, flags=re.M)
    else:
        text = re.sub(r"^noise_seed = .*$", f"noise_seed = {seed}", text, flags=re.M)
        text = re.sub(r"^seed = .*$", f"seed = {seed}", text, flags=re.M)
    path = Path(directory) / f"calibration_{'noiseless' if seed is None else seed}.toml"
    path.write_text(text)
    return path


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


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", default="1-20", help="noise seeds, e.g. 1-20 or 1,5,7-9 (default 1-20)")
    ap.add_argument("--out", default=None, help="directory for calibration.csv (default: a temporary one)")
    ap.add_argument("--importance", default="", help="seeds to check by importance sampling, e.g. 2,3")
    ap.add_argument("--noiseless", action="store_true", help="also the posterior of the noiseless twin")
    args = ap.parse_args(argv)
    seeds = _seeds(args.seeds)
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
