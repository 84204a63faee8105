"""LMI designs of the Bejarano et al. estimator (eqs. (15)-(16), (25), (26)-(28), (48)).

Both problems minimise the ISS gain bound beta subject to a Lyapunov decrease LMI, an alpha-stability
half-plane LMI ``Re(lambda) <= -delta`` (Chilali-Gahinet-Apkarian 1999) and, as a documented deviation,
a disk region ``|lambda| <= rho``: without it the objective is flat in the gains and the solver
returns spurious poles near -1e8 (see ``shared/reference/baselines.md`` section 2.4). For large delta the
problem is solved in time-scaled coordinates ``t' = s t`` (``s = delta``) with the states of the
integrator chain scaled by ``diag(1, s, s^2)``: A stays, ``r, delta, rho`` are divided by ``s`` and the gain's
block rows are multiplied back by ``s, s^2, s^3``. This is exact for the poles and avoids a badly scaled
SDP; the "+I" normalisation of (16c)/(28c) then holds in the scaled coordinates.

Even with the disk, beta's infimum is not attained when no noise term bounds W (the rotational problem always,
the positional one with k_n = 0): it is approached as P grows ill-conditioned (eigenvalues 0.03 to 4e3 and
spreading), so the gains are wherever the interior-point iterations stop — 5-17 % apart on two CPUs, 60 %
apart at tighter tolerances. A second documented deviation makes the optimum attained: the objective is
``beta + mu trace(P)`` (``trace_weight``, default 1e-3), whose solution agrees to 1e-5 between CLARABEL's
default and 1e-11 tolerances. Where noise bounds W (k_n = 1) the gains move by < 1e-4 relative.

Symbols -> code: P_psi -> ``P``, W_psi -> ``W``, beta_psi -> ``beta``, delta_{psi,1} -> ``delta``,
L_{p_z} = P_p^-1 W_p -> ``L_pz``, k_{omega,p} -> ``k_omega``, k_{n,p} -> ``k_n``.
"""

from __future__ import annotations

import os
import sys
import tempfile
import threading
import warnings
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from functools import lru_cache
from typing import TYPE_CHECKING

import numpy as np

from marinebench.errors import DesignError

if TYPE_CHECKING:  # cvxpy is imported where an LMI is solved: it costs ~60 MiB and ~1 s, which the DP and ROV
    import cvxpy as cp  # worlds' runs and sweeps (and their worker processes) never need

A_PSI = np.array([[0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [0.0, 0.0, 0.0]])
C_PSI = np.array([[1.0, 0.0, 0.0]])
BW_PSI = np.array([[0.0], [0.0], [1.0]])

I2, Z2 = np.eye(2), np.zeros((2, 2))
A0_P = np.block([[Z2, I2, Z2], [Z2, Z2, I2], [Z2, Z2, Z2]])  # eq. (29)
S_P = np.array([[0.0, -1.0], [1.0, 0.0]])
S_TP = np.block([[S_P.T, Z2, Z2], [Z2, Z2, Z2], [Z2, Z2, Z2]])  # S_{T_p} of eq. (29)
C_P = np.hstack([I2, Z2, Z2])
BW_P = np.vstack([Z2, Z2, I2])


@dataclass(frozen=True)
class LmiSolution:
    """Solution of one design problem, in original (unscaled) time."""

    gain: np.ndarray  # L_psi (3, 1) with A - L C, or L_pz (6, 2) with A0 + r S + L_pz C
    P: np.ndarray
    W: np.ndarray
    beta: float
    time_scale: float
    poles: np.ndarray  # closed-loop poles at the r vertices (and r = 0), flattened


def _sym(X: cp.Expression) -> cp.Expression:
    return (X + X.T) / 2


SOLVER_OPTIONS: dict[str, float] = {}  # CLARABEL settings (its defaults); tests tighten them to show the gains do not move


@lru_cache(maxsize=1)
def _one_thread() -> dict[str, int]:
    """``max_threads=1`` where CLARABEL has the setting (>= 0.10). Otherwise CLARABEL starts a pool of one thread per
    core on the first problem that uses its parallel parts (the positional LMI with k_n > 0), and a process forked
    after that (``--jobs`` workers) would wait for ever on pool threads the fork did not copy as soon as it solved
    a problem of its own. The designs are small (milliseconds) and their gains are the same to the bit."""
    import clarabel

    return {"max_threads": 1} if hasattr(clarabel.DefaultSettings(), "max_threads") else {}


def solve(problem: cp.Problem, what: str, options: dict[str, float] | None = None) -> None:
    """Solve with CLARABEL; 'inaccurate' solutions are accepted because the designs re-check them in numpy.

    A solver that fails, or panics (CLARABEL is Rust: on extreme data such as a weight of 1e300 it can abort with a
    ``pyo3_runtime.PanicException``, which derives from BaseException), or a problem that is not solved, raises
    :class:`DesignError` naming ``what``; what the panic wrote to stderr is dropped (:func:`_stderr_unless_panic`).
    CLARABEL runs in this thread alone (:func:`_one_thread`), so a process forked later can solve too."""
    import cvxpy as cp

    settings = _one_thread() | (SOLVER_OPTIONS if options is None else options)  # the caller's win
    try:
        with warnings.catch_warnings(), _stderr_unless_panic():
            warnings.simplefilter("ignore", UserWarning)
            problem.solve(solver=cp.CLARABEL, **settings)
    except cp.error.SolverError as exc:
        raise DesignError(f"{what}: solver failed ({exc})") from None
    except BaseException as exc:
        if not _is_panic(exc):  # KeyboardInterrupt and the rest go on up
            raise
        raise DesignError(f"{what}: the solver crashed ({exc}); are the settings within a sensible range?") from None
    if problem.status not in (cp.OPTIMAL, cp.OPTIMAL_INACCURATE):
        raise DesignError(f"{what}: LMI problem is {problem.status}")


def _is_panic(exc: BaseException) -> bool:
    return type(exc).__name__ == "PanicException"


_STDERR_HELD = threading.Lock()  # one solve at a time holds file descriptor 2 (two would restore each other's copy)


@contextmanager
def _stderr_unless_panic() -> Iterator[None]:
    """Hold file descriptor 2 in a temporary file and write it back to stderr unless the block raised a panic: Rust's
    panic hook writes its message, and under ``RUST_BACKTRACE`` a backtrace of 100+ lines, straight to fd 2 before
    the exception reaches Python, where :func:`solve` says it in one line. Other threads' stderr output during a
    solve (milliseconds) comes after it; without an fd 2 the block runs as it is."""
    with _STDERR_HELD:
        try:
            saved = os.dup(2)
        except OSError:
            yield
            return
        with tempfile.TemporaryFile() as held:
            _flush_stderr()
            os.dup2(held.fileno(), 2)
            panicked = False
            try:
                yield
            except BaseException as exc:
                panicked = _is_panic(exc)
                raise
            finally:
                _flush_stderr()
                os.dup2(saved, 2)
                os.close(saved)
                if not panicked:
                    held.seek(0)
                    _write_fd2(held.read())


def _flush_stderr() -> None:
    if sys.stderr is not None:  # None under pythonw
        sys.stderr.flush()


def _write_fd2(data: bytes) -> None:
    while data:
        data = data[os.write(2, data) :]


def _scale_rows(gain: np.ndarray, s: float, block: int) -> np.ndarray:
    """Map a gain designed in time-scaled coordinates back: block row i is multiplied by s**(i+1)."""
    out = gain.copy()
    for i in range(gain.shape[0] // block):
        out[i * block : (i + 1) * block] *= s ** (i + 1)
    return out


@lru_cache(maxsize=256)
def rotational_design(delta: float, rho: float, scale_above: float = 50.0, trace_weight: float = 1e-3) -> LmiSolution:
    """Rotational gain L_psi = -P_psi^-1 W_psi from problem (16) with (25), a disk |lambda| <= rho and the
    objective beta + trace_weight tr(P)."""
    import cvxpy as cp

    s = delta if delta >= scale_above else 1.0
    d, r_ = delta / s, rho / s
    P = cp.Variable((3, 3), symmetric=True)
    W = cp.Variable((3, 1))
    beta = cp.Variable()
    lyap = A_PSI.T @ P + P @ A_PSI + C_PSI.T @ W.T + W @ C_PSI
    PA = P @ A_PSI + W @ C_PSI
    cons = [
        P >> 1e-6 * np.eye(3),
        _sym(lyap + np.eye(3)) << 0,  # (16c)
        _sym(cp.bmat([[-beta * np.eye(3), P @ BW_PSI], [(P @ BW_PSI).T, -beta * np.eye(1)]])) << 0,  # (16d)
        _sym(lyap + 2 * d * P) << 0,  # (25)
        _sym(cp.bmat([[-r_ * P, PA], [PA.T, -r_ * P]])) << 0,  # disk region
    ]
    solve(cp.Problem(cp.Minimize(beta + trace_weight * cp.trace(P)), cons), f"rotational LMI (delta_psi1={delta}, rho={rho})")
    L_bar = -np.linalg.solve(P.value, W.value)
    L = _scale_rows(L_bar, s, 1)
    poles = np.linalg.eigvals(A_PSI - L @ C_PSI)
    return LmiSolution(L, P.value, W.value, float(beta.value), s, poles)


@lru_cache(maxsize=256)
def positional_design(
    delta: float,
    k_omega: float,
    k_n: float,
    r_min: float,
    r_max: float,
    rho: float,
    scale_above: float = 50.0,
    trace_weight: float = 1e-3,
) -> LmiSolution:
    """Positional gain L_pz = P_p^-1 W_p from problem (28) with (48), a disk |lambda| <= rho and the objective
    beta + trace_weight tr(P)."""
    import cvxpy as cp

    s = delta if delta >= scale_above else 1.0
    d, r_ = delta / s, rho / s
    A0 = A0_P  # invariant under z -> diag(1, s, s^2) z combined with t' = s t
    P = cp.Variable((6, 6), symmetric=True)
    W = cp.Variable((6, 2))
    beta = cp.Variable()
    cons = [P >> 1e-6 * np.eye(6)]
    for r in (r_min / s, r_max / s):
        lyap = A0.T @ P + P @ A0 + C_P.T @ W.T + W @ C_P + r * (S_TP.T @ P + P @ S_TP)
        cons += [_sym(lyap + np.eye(6)) << 0, _sym(lyap + 2 * d * P) << 0]  # (28c,d), (48)
        PA = P @ (A0 + r * S_TP) + W @ C_P
        cons += [_sym(cp.bmat([[-r_ * P, PA], [PA.T, -r_ * P]])) << 0]  # disk region
    U = cp.bmat(
        [
            [-beta * np.eye(6), k_omega * (P @ BW_P), k_n * W],
            [k_omega * (P @ BW_P).T, -beta * np.eye(2), np.zeros((2, 2))],
            [k_n * W.T, np.zeros((2, 2)), -beta * np.eye(2)],
        ]
    )
    cons += [_sym(U) << 0]  # (28e)
    what = f"positional LMI (delta_p1={delta}, k_omega={k_omega}, k_n={k_n}, rho={rho})"
    solve(cp.Problem(cp.Minimize(beta + trace_weight * cp.trace(P)), cons), what)
    L_bar = np.linalg.solve(P.value, W.value)
    L = _scale_rows(L_bar, s, 2)
    poles = np.concatenate([np.linalg.eigvals(A0_P + r * S_TP + L @ C_P) for r in (r_min, 0.0, r_max)])
    return LmiSolution(L, P.value, W.value, float(beta.value), s, poles)


def verify(sol: LmiSolution, delta: float, rho: float, tol: float = 1e-6) -> list[str]:
    """Independent numpy checks of a design: P > 0 and every pole inside the requested region.

    Returns a list of human-readable failures (empty when the design is valid).
    """
    problems = []
    if np.min(np.linalg.eigvalsh((sol.P + sol.P.T) / 2)) <= 0:
        problems.append("P is not positive definite")
    worst_re = float(np.max(sol.poles.real))
    if worst_re > -delta + tol * max(1.0, delta):
        problems.append(f"slowest pole Re={worst_re:.4g} is right of -delta={-delta:.4g}")
    worst_abs = float(np.max(np.abs(sol.poles)))
    if worst_abs > rho * (1 + 1e-4):
        problems.append(f"fastest pole |lambda|={worst_abs:.4g} exceeds rho={rho:.4g}")
    return problems
