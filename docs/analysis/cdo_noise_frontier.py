"""Can any gain of the CDO's structure pass 20 % less depth sample noise than the EO, and how fast can it then
converge?  (docs/tijjani.md, *CDO vs EO*)

Tijjani's Fig. 2 claim, as the issue states it: the CDO's observation RMSE at least 20 % below the extended
high-gain observer's (EO), for depth and for yaw.  In depth it fails here (CDO +52 % against the truth), and
after the transient the depth error is the white sample noise passed through each observer.  So the question is
one about gains, not about a world: with the truth at rest, each DOF of either observer is a linear 3-state
error chain between samples (``design/cdo.py``: ``sampled_flow``; the CDO with its inter-sample predictor
``w' = x_hat_2 + K_w (w - x_hat_1)``, the EO on the held sample), so for an injection gain L (3-vector,
physical units) two numbers describe it:

- r(L): the spectral radius of the per-sample error map, how much the estimation error contracts per sample
  (below 1 iff the observer converges at all);
- g(L): the std of the position estimate per unit std of white sample noise, averaged over the sample period
  (a discrete Lyapunov equation and an exact integral over the period).

Both come from ``design.cdo.sample_noise_gains``, the function behind the manifests' ``noise_gain_*``.  The
*frontier* of a structure is g*(r) = min over L of g(L) subject to r(L) <= r: the least noise any gain of that
structure passes while contracting at least that fast.  It is found by a seeded, batched elite search over
log L polished by Nelder-Mead (``frontier``), so each point is an upper bound on the true frontier; two
independent searches (``SEEDS``) agree within 1 % for r >= 0.7 and within 8 % at r = 0.3-0.5, and the better
of the two is kept.  Run (about 2 minutes on 2 cores):

    python docs/analysis/cdo_noise_frontier.py

``tests/test_docs_quote_results.py`` recomputes the defaults docs/tijjani.md quotes (``defaults``) and checks
that the quoted frontier gains reach the quoted radius and noise gain.
"""

from __future__ import annotations

import numpy as np
from scipy.optimize import minimize

from marinebench.design.cdo import sample_noise_gains, sampled_radius
from marinebench.observers.cdo import CdoParams, EoParams

H_DEPTH = 0.05  # s, the pressure sensor's period (Tijjani Table I)
RADII = (0.3, 0.5, 0.7, 0.78, 0.85, 0.9)  # per-sample contraction targets
N_SEARCH = 20_000  # first, uniform population of log L per structure
ROUNDS, N_ROUND, N_ELITE = 30, 2_000, 40  # elite search: rounds, points per round, elites kept
LOG_RANGE = ((-1.0, -2.0, -3.0), (4.0, 7.0, 10.0))  # log10 of L_1, L_2, L_3
TARGET = 0.8  # "at least 20 % below"
SEEDS = (0, 1)  # independent searches; each frontier point is the better one


def _cost(r: np.ndarray, g: np.ndarray, target: float) -> np.ndarray:
    """g where the contraction target holds, else a penalty above every feasible g that falls as r nears it."""
    return np.where(r <= target, g, 1e3 * (1.0 + r - target))


def frontier(h: float, k_w: float, predictor: bool, start: np.ndarray, radii=RADII,
             seed: int = 0) -> dict[float, tuple[float, np.ndarray]]:
    """g*(r) and its gain L for each r in ``radii``, by a seeded, batched elite search over log L: a uniform
    population plus ``start`` (the structure's default gain) and, for each target, the faster target's optimum
    (feasible for every slower one, so g* never rises as r grows); then ``ROUNDS`` rounds that keep the
    ``N_ELITE`` best and resample ``N_ROUND`` points around them with a spread shrinking from 0.5 to 0.002
    decades; then Nelder-Mead from the best."""
    rng = np.random.default_rng(seed)
    lo, hi = np.array(LOG_RANGE[0]), np.array(LOG_RANGE[1])
    pop = np.vstack([rng.uniform(lo, hi, size=(N_SEARCH, 3)), np.log10(start)])
    out: dict[float, tuple[float, np.ndarray]] = {}
    for target in sorted(radii):
        logs = pop if not out else np.vstack([pop, np.log10(out[max(out)][1])])
        r, g = sample_noise_gains(10.0**logs, h, k_w, predictor)
        for spread in np.geomspace(0.5, 0.002, ROUNDS):
            keep = np.argsort(_cost(r, g, target))[:N_ELITE]
            picks = logs[keep][rng.integers(N_ELITE, size=N_ROUND)]
            trial = np.clip(picks + spread * rng.standard_normal((N_ROUND, 3)), lo, hi)
            rt, gt = sample_noise_gains(10.0**trial, h, k_w, predictor)
            logs, r, g = np.vstack([logs[keep], trial]), np.concatenate([r[keep], rt]), np.concatenate([g[keep], gt])
        best = logs[np.argmin(_cost(r, g, target))]
        polish = minimize(lambda x, t=target: _cost(*sample_noise_gains(10.0 ** x[None], h, k_w, predictor), t)[0], best,
                          method="Nelder-Mead", bounds=list(zip(lo, hi)), options={"xatol": 1e-5, "fatol": 1e-7})
        fine_r, fine_g = sample_noise_gains(10.0 ** np.vstack([best, polish.x]), h, k_w, predictor)
        ok = fine_r <= target
        i = int(np.argmin(np.where(ok, fine_g, np.inf)))
        out[target] = (float(fine_g[i]), 10.0 ** np.vstack([best, polish.x])[i]) if ok[i] else (np.inf, np.full(3, np.nan))
    return out


def defaults() -> dict[str, float]:
    """Both observers' default gains in depth: per-sample radius r and sample-noise gain g (cheap)."""
    cdo, eo = CdoParams(), EoParams()
    (cdo_r,), (cdo_g,) = sample_noise_gains(cdo.injection(), H_DEPTH, cdo.k_w)
    (eo_r,), (eo_g,) = sample_noise_gains(eo.gain(), H_DEPTH, predictor=False)
    assert np.isclose(cdo_r, sampled_radius(cdo.gain(), cdo.theta, cdo.k_w, H_DEPTH))
    return {"cdo_default_radius": cdo_r, "cdo_default_gain": cdo_g, "eo_default_radius": eo_r,
            "eo_default_gain": eo_g, "needed_gain": TARGET * eo_g}


def analysis(seeds=SEEDS) -> dict[str, float]:
    """The figures docs/tijjani.md quotes: both observers' defaults and both frontiers in depth, each frontier
    point the better of the searches over ``seeds`` (with the relative spread between them)."""
    cdo, eo = CdoParams(), EoParams()
    result = defaults()
    for name, predictor, k_w, start in (("cdo", True, cdo.k_w, cdo.injection()), ("eo", False, 0.0, eo.gain())):
        runs = [frontier(H_DEPTH, k_w, predictor, np.asarray(start, float), seed=seed) for seed in seeds]
        for r in RADII:
            values = [run[r][0] for run in runs]
            result[f"{name}_frontier_{r}"], result[f"{name}_frontier_{r}_gain"] = min((run[r] for run in runs),
                                                                                        key=lambda vg: vg[0])
            result[f"{name}_frontier_{r}_spread"] = max(values) / min(values) - 1
    reach = [r for r in RADII if result[f"cdo_frontier_{r}"] <= result["needed_gain"]]
    result["cdo_first_radius_below_target"] = min(reach) if reach else np.inf
    return result


if __name__ == "__main__":
    res = analysis()
    print(f"EO default: r = {res['eo_default_radius']:.3f} per {H_DEPTH * 1e3:.0f} ms sample, g = {res['eo_default_gain']:.3f}")
    print(f"CDO default: r = {res['cdo_default_radius']:.3f}, g = {res['cdo_default_gain']:.3f}")
    print(f"20 % below the EO needs g <= {res['needed_gain']:.3f}")
    print("r      CDO g*(r)  (spread)  EO g*(r)  (spread)  CDO's K* = L / (theta, theta^2, theta^3)")
    theta = CdoParams().theta
    for r in RADII:
        k_star = res[f"cdo_frontier_{r}_gain"] / np.array([theta, theta**2, theta**3])
        print(f"{r:<6} {res[f'cdo_frontier_{r}']:9.3f} {100 * res[f'cdo_frontier_{r}_spread']:7.1f} % "
              f"{res[f'eo_frontier_{r}']:9.3f} {100 * res[f'eo_frontier_{r}_spread']:7.1f} %   {np.round(k_star, 4).tolist()}")
