"""Gains of Tijjani's continuous-discrete observer (CDO, eq. (38)): the LMIs (39)-(40) and the sampled-data check.

Per DOF the CDO is a 3-state chain in high-gain coordinates (baselines.md s.9):

    x_hat' = A x_hat + B u + Delta_theta K* (w - C x_hat),   w' = C (A x_hat + B u) + K_w (w - C x_hat),
    w(t_k) = y(t_k),   A = [[0,1,0],[0,0,1],[0,0,0]],  C = [1 0 0],  Delta_theta = diag(theta, theta^2, theta^3).

LMI (40), linear in (P, Y = P K*, S) with lambda > 0 given:

    [[A^T P + P A - C^T Y^T - Y C,  Y C], [C^T Y^T, -S]]  <=  -lambda I,   P > 0, S > 0.

As printed, (40) constrains K* only through feasibility (any Hurwitz A - K* C passes for a large enough S),
so the design adds what makes it a design: a decay rate ``A_cl^T P + P A_cl <= -2 mu P`` (poles of the
normalised observer left of -mu, i.e. left of -mu theta once scaled) and minimises trace(S), the bound on
how much the prediction error w - C x_hat feeds the estimation error; P >= I fixes the scale.
(39) reduces per DOF to the scalar K_w < theta K*_1 (the prediction error obeys z' = (K_w - theta K*_1) z).
(41) is not reproduced (its printed entries contain typos, baselines.md 9.3); the sampled-data check
replaces it: the error (e_x, e_y) flows with F = [[A - Delta K* C, Delta K*], [C A - K_w C, K_w]] over
one sample period h and e_y resets to 0 at the sample, so the observer converges iff the spectral radius
of the top-left 3x3 block of expm(F h) is below 1.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from scipy.linalg import expm

from marinebench.design.lmi import solve
from marinebench.errors import DesignError

A = np.array([[0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [0.0, 0.0, 0.0]])
C = np.array([[1.0, 0.0, 0.0]])
BINOMIAL = (3.0, 3.0, 1.0)


@dataclass(frozen=True)
class CdoDesign:
    k_star: tuple[float, float, float]
    P: np.ndarray | None
    S: np.ndarray | None
    lmi_max_eig: float | None  # largest eigenvalue of the LMI (40) matrix + lambda I at the solution (<= 0)
    poles_normalised: np.ndarray  # eigenvalues of A - K* C (times theta: the continuous observer's poles)


@lru_cache(maxsize=32)
def design_lmi(mu: float, lam: float = 1e-3) -> CdoDesign:
    """Solve LMI (40) with the decay rate ``mu`` and minimal trace(S) (CLARABEL), then verify in numpy."""
    import cvxpy as cp  # here, not at the top: see design/lmi.py

    P = cp.Variable((3, 3), symmetric=True)
    Y = cp.Variable((3, 1))
    S = cp.Variable((3, 3), symmetric=True)
    lyap = A.T @ P + P @ A - C.T @ Y.T - Y @ C
    big = cp.bmat([[lyap, Y @ C], [(Y @ C).T, -S]])
    cons = [
        (big + big.T) / 2 << -lam * np.eye(6),
        (lyap + lyap.T) / 2 << -2 * mu * P,
        P >> np.eye(3),
        S >> 0,
    ]
    prob = cp.Problem(cp.Minimize(cp.trace(S)), cons)
    solve(prob, f"CDO LMI (40) with mu={mu}", options={})  # CLARABEL's defaults
    if P.value is None:
        raise DesignError(f"CDO LMI (40) with mu={mu}: no solution ({prob.status})")
    Pv, Yv, Sv = P.value, Y.value, S.value
    k = np.linalg.solve(Pv, Yv).ravel()
    return CdoDesign(tuple(float(v) for v in k), Pv, Sv, verify_lmi(k, Pv, Sv, lam, mu), np.linalg.eigvals(A - np.outer(k, C)))


def verify_lmi(k_star: np.ndarray, P: np.ndarray, S: np.ndarray, lam: float, mu: float, tol: float = 1e-6) -> float:
    """Re-check (40) and the decay rate in numpy for the recovered K*; raises DesignError if violated."""
    k = np.asarray(k_star, dtype=float).reshape(3, 1)
    a_cl = A - k @ C
    lyap = a_cl.T @ P + P @ a_cl
    big = np.block([[lyap, P @ k @ C], [(P @ k @ C).T, -S]])
    worst = float(np.linalg.eigvalsh((big + big.T) / 2 + lam * np.eye(6)).max())
    decay = float(np.linalg.eigvalsh((lyap + lyap.T) / 2 + 2 * mu * P).max())
    scale = max(1.0, np.abs(P).max(), np.abs(S).max())
    if worst > tol * scale or decay > tol * scale or np.linalg.eigvalsh(P).min() <= 0:
        raise DesignError(f"CDO LMI (40) solution fails the numpy check (max eig {worst:.2e}, decay {decay:.2e})")
    return worst


def sampled_flow(injection, k_w: float = 0.0, predictor: bool = True) -> np.ndarray:
    """4x4 flow between samples of the estimation error ``x_hat - x`` and the output-channel error ``w - y``.

    ``injection`` is the 3-vector on the output error (or a batch (..., 3) -> (..., 4, 4)) (Delta_theta K* for the CDO, [a_i / eps^i] for the EO).
    The CDO's predictor obeys ``w' = x_hat_2 + K_w (w - x_hat_1)``; without it (``predictor=False``, the EO)
    the output channel is the held sample, constant between samples (with the truth at rest).
    """
    lk = np.asarray(injection, dtype=float)
    F = np.zeros((*lk.shape[:-1], 4, 4))
    F[..., :3, :3] = A - lk[..., :, None] * C
    F[..., :3, 3] = lk
    if predictor:
        F[..., 3, :3] = (C @ A - k_w * C).ravel()
        F[..., 3, 3] = k_w
    return F


def sampled_radius(k_star, theta: float, k_w: float, h: float) -> float:
    """Spectral radius of the per-sample error map (the CDO converges iff < 1); ``inf`` where the map overflows
    (extreme theta, K_w or h)."""
    with np.errstate(over="ignore", invalid="ignore"):
        Fh = sampled_flow(theta ** np.arange(1.0, 4.0) * np.asarray(k_star, dtype=float), k_w) * h
        E = expm(Fh)[:3, :3] if np.isfinite(Fh).all() else np.full((3, 3), np.inf)
    return float(np.abs(np.linalg.eigvals(E)).max()) if np.isfinite(E).all() else float("inf")


def sample_noise_gains(injections, h: float, k_w: float = 0.0, predictor: bool = True,
                       halvings: int = 12) -> tuple[np.ndarray, np.ndarray]:
    """Per-sample error radius and sample-noise gain of a batch of injection gains (n, 3), truth at rest.

    The radius is that of ``sampled_radius`` (top-left 3x3 block of ``E = expm(F h)``). The gain is the std of the
    position estimate per unit std of white noise on the samples (period ``h``): the state just after a sample
    (the output channel restarted from the noisy sample) has the stationary covariance
    ``P = (J E) P (J E)^T + e4 e4^T``, ``J`` zeroing the output channel (a discrete Lyapunov equation, solved by
    a Kronecker product); the gain is ``sqrt`` of the position variance averaged over the period,
    ``[X]_00 / h`` with ``X = int_0^h expm(F s) P expm(F s)^T ds`` computed exactly: Van Loan's block
    exponential over ``h / 2**halvings``, then doubled (``X(2d) = X(d) + E(d) X(d) E(d)^T``), so that stiff
    gains lose no accuracy. ``inf`` where the radius is >= 1. It is the steady-state noise-to-estimate gain the
    RMSE sees when the noise, not the motion, dominates (docs/tijjani.md, CDO vs EO).
    """
    F = sampled_flow(np.atleast_2d(np.asarray(injections, dtype=float)), k_w, predictor)
    E = expm(F * h)
    radius = np.abs(np.linalg.eigvals(E[:, :3, :3])).max(axis=1)
    gain = np.full(len(F), np.inf)
    ok = radius < 1
    if not ok.any():
        return radius, gain
    F, K = F[ok], E[ok].copy()
    K[:, 3, :] = 0.0  # J E: the output channel restarts from the sample
    q = np.zeros(16)
    q[15] = 1.0  # the sample's unit noise enters the output channel
    kron = np.einsum("nij,nkl->nikjl", K, K).reshape(-1, 16, 16)
    P = np.linalg.solve(np.eye(16) - kron, np.broadcast_to(q, (len(K), 16))[..., None])[..., 0].reshape(-1, 4, 4)
    block = np.zeros((len(F), 8, 8))
    block[:, :4, :4], block[:, :4, 4:], block[:, 4:, 4:] = F, P, -np.swapaxes(F, 1, 2)
    M = expm(block * (h / 2**halvings))
    step, X = M[:, :4, :4], M[:, :4, 4:] @ np.swapaxes(M[:, :4, :4], 1, 2)
    for _ in range(halvings):
        X = X + step @ X @ np.swapaxes(step, 1, 2)
        step = step @ step
    gain[ok] = np.sqrt(X[:, 0, 0] / h)
    return radius, gain


def sample_noise_gain(injection, h: float, k_w: float = 0.0, predictor: bool = True) -> float:
    """``sample_noise_gains`` of one injection gain (the sample-noise gain, ``inf`` if it does not converge)."""
    return float(sample_noise_gains(injection, h, k_w, predictor)[1][0])


def check(k_star, theta: float, k_w: float, h: float, dof: str) -> float:
    """(39) and the sampled-data condition for one DOF; returns the spectral radius, raises DesignError."""
    if not k_w < theta * k_star[0]:
        raise DesignError(f"CDO {dof}: (39) needs K_w < theta K*_1 ({k_w} >= {theta * k_star[0]:.3g})")
    rho = sampled_radius(k_star, theta, k_w, h)
    if not rho < 1:
        raise DesignError(f"CDO {dof}: the per-sample error map has spectral radius {rho:.3f} >= 1 at h = {h} s")
    return rho
