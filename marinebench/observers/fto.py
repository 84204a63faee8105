"""Finite-time-observer algebra of the resetting observer (Torben et al. eqs. (12)-(26)), batched.

Two Luenberger observers z1, z2 (gains L1, L2) and their transition matrices Phi1, Phi2 are propagated
over a window of length delta; at the window end (Torben eq. (16), with the *propagated* Phi):

    Y  = Phi2 Phi1^-1          (linear solve with Phi1^T, never an explicit inverse)
    X  = I - Y
    z* = X^-1 (z2 - Y z1)      (= Psi [z1; z2]; linear solve)

and z1 jumps to ``k z* + (1 - k) z1`` when some output error ``|y - C z1|_i >= eps_i`` and
``cond(X) <= c_max`` (the check can be switched off). The condition number is evaluated in the
coordinates given by ``scale`` (``X_s = S^-1 X S``, ``S = diag(scale)``; the bis system for DP), where
c_max applies.

Discretisation: for a step dt with the heading and the inputs held, the linear flow
``z' = A_i z + w`` is advanced by the RK4 one-step map ``z+ = P z + H w`` with ``X = A_i dt``,
``P = I + X + X^2/2 + X^3/6 + X^4/24`` and ``H = dt (I + X/2 + X^2/6 + X^3/24)``; Phi_i uses the same P.
"""

from __future__ import annotations

import numpy as np


def rk4_maps(A: np.ndarray, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """Batched RK4 one-step maps ``(P, H)`` of ``z' = A z + w`` (w held), for ``A (..., n, n)``."""
    n = A.shape[-1]
    eye = np.broadcast_to(np.eye(n), A.shape)
    X = A * dt
    # Horner: H/dt = I + X/2 (I + X/3 (I + X/4)),  P = I + X H/dt
    inner = eye + X @ (eye + X / 4) / 3
    Hn = eye + X @ inner / 2
    return eye + X @ Hn, dt * Hn


def fto_jump(
    z1: np.ndarray,
    z2: np.ndarray,
    phi1: np.ndarray,
    phi2: np.ndarray,
    innovation: np.ndarray,
    k: np.ndarray,
    eps: np.ndarray,
    c_max: float | np.ndarray,
    scale: np.ndarray,
    check: bool | np.ndarray = True,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Jump map for a batch of window ends. Returns ``(z1_plus, jumped, cond)``.

    Shapes: z (B, n), phi (B, n, n), innovation and eps (B, p), k (B,); ``c_max`` and ``check`` a scalar or
    one per run; ``scale`` (n,) or one row per run (B, n). ``cond`` is evaluated for every window end (the
    observer's diagnostics; ``inf`` for a run gone non-finite, which does not jump and is left for the engine to
    flag as diverged); ``z*`` is solved only for the runs that jump, which at a sweep's window ends are few.
    """
    n = z1.shape[1]
    sc = np.broadcast_to(scale, z1.shape)  # (B, n): each run's coordinates
    with np.errstate(all="ignore"):
        # everything in the scaled coordinates z_s = S^-1 z, where Phi and X are far better conditioned
        p1 = phi1 * sc[:, None, :] / sc[:, :, None]
        p2 = phi2 * sc[:, None, :] / sc[:, :, None]
        Ys = np.linalg.solve(np.swapaxes(p1, 1, 2), np.swapaxes(p2, 1, 2)).swapaxes(1, 2)  # Ys p1 = p2
        Xs = np.eye(n) - Ys
        finite = np.isfinite(Xs).all(axis=(1, 2))  # not where a run has diverged (its SVD would raise, for the batch)
        cond = np.full(len(Xs), np.inf)
        cond[finite] = np.linalg.cond(Xs[finite]) if finite.any() else []
        jumped = (np.abs(innovation) >= eps).any(axis=1) & finite
        jumped &= ~np.asarray(check) | (cond <= c_max)
        j = np.flatnonzero(jumped)
        if j.size:
            nonsingular = np.abs(np.linalg.det(Xs[j])) > 0
            jumped[j[~nonsingular]] = False
            j = j[nonsingular]
        z_plus = z1.copy()
        if j.size:
            rhs = z2[j] / sc[j] - np.einsum("bij,bj->bi", Ys[j], z1[j] / sc[j])
            z_star = np.linalg.solve(Xs[j], rhs[..., None])[..., 0] * sc[j]
            kj = k[j, None]
            z_plus[j] = kj * z_star + (1 - kj) * z1[j]
    return z_plus, jumped, cond
