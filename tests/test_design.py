"""LMI designs re-verified independently of the solver (numpy only)."""

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from marinebench.design.lmi import (
    A0_P,
    A_PSI,
    BW_P,
    BW_PSI,
    C_P,
    C_PSI,
    S_TP,
    positional_design,
    rotational_design,
    verify,
)
from marinebench.errors import DesignError
from marinebench.observers.bejarano import BejaranoTuning, design

CONFIGS = Path(__file__).parent.parent / "configs"


def max_eig(X):
    return np.max(np.linalg.eigvalsh((X + X.T) / 2))


def test_structure_matrices_are_the_papers():
    """The rotational chain (psi, r, sigma_r) measured in psi with the disturbance on sigma_r, and eq. (29):
    A0_p the 2x2-block integrator chain, S_Tp = blockdiag(S_p^T, 0, 0) with S_p = [[0, -1], [1, 0]], C_p = [I 0 0],
    B_omega,p = [0 0 I]^T."""
    np.testing.assert_array_equal(A_PSI, [[0, 1, 0], [0, 0, 1], [0, 0, 0]])
    np.testing.assert_array_equal(C_PSI, [[1, 0, 0]])
    np.testing.assert_array_equal(BW_PSI, [[0], [0], [1]])
    I2, Z2 = np.eye(2), np.zeros((2, 2))
    np.testing.assert_array_equal(A0_P, np.block([[Z2, I2, Z2], [Z2, Z2, I2], [Z2, Z2, Z2]]))
    np.testing.assert_array_equal(S_TP[:2, :2], [[0, 1], [-1, 0]])
    assert not S_TP[2:].any() and not S_TP[:, 2:].any()
    np.testing.assert_array_equal(C_P, np.hstack([I2, Z2, Z2]))
    np.testing.assert_array_equal(BW_P, np.vstack([Z2, Z2, I2]))


@pytest.mark.parametrize("delta,rho", [(0.05, 50.0), (2.2, 50.0), (300.0, 1500.0)])
def test_rotational_lmis_hold(delta, rho):
    sol = rotational_design(delta, rho)
    assert verify(sol, delta, rho) == []
    P, W, s = sol.P, sol.W, sol.time_scale
    assert np.min(np.linalg.eigvalsh(P)) > 0
    lyap = A_PSI.T @ P + P @ A_PSI + C_PSI.T @ W.T + W @ C_PSI
    scale = np.abs(P).max()
    assert max_eig(lyap + np.eye(3)) <= 1e-6 * scale  # (16c) in the (possibly time-scaled) coordinates
    assert max_eig(lyap + 2 * delta / s * P) <= 1e-6 * scale  # (25)
    assert np.linalg.norm(P @ BW_PSI, 2) <= sol.beta * (1 + 1e-6)  # (16d) <=> ||P B|| <= beta
    poles = np.linalg.eigvals(A_PSI - sol.gain @ C_PSI)
    assert poles.real.max() <= -delta * (1 - 1e-6)
    assert np.abs(poles).max() <= rho * (1 + 1e-6)


@pytest.mark.parametrize("delta,kw,kn,rho", [(0.05, 1, 0, 50.0), (1.2, 1, 1, 50.0), (400.0, 1, 0, 2000.0), (0.0, 100, 1, 50.0),
                                             (1.2, 2.5, 0.4, 50.0)])
def test_positional_lmis_hold(delta, kw, kn, rho):
    r_max = 0.8727
    sol = positional_design(delta, kw, kn, -r_max, r_max, rho)
    assert verify(sol, delta, rho) == []
    P, W, s = sol.P, sol.W, sol.time_scale
    scale = np.abs(P).max()
    for r in (-r_max / s, r_max / s):
        lyap = A0_P.T @ P + P @ A0_P + C_P.T @ W.T + W @ C_P + r * (S_TP.T @ P + P @ S_TP)
        assert max_eig(lyap + np.eye(6)) <= 1e-6 * scale  # (28c), (28d)
        assert max_eig(lyap + 2 * delta / s * P) <= 1e-6 * scale  # (48)
    upsilon = np.hstack([kw * P @ BW_P, kn * W])
    assert np.linalg.norm(upsilon, 2) <= sol.beta * (1 + 1e-5)  # (28e) <=> ||Upsilon|| <= beta
    for r in np.linspace(-r_max, r_max, 7):  # the vertex LMIs cover the whole yaw-rate interval
        assert np.linalg.eigvals(A0_P + r * S_TP + sol.gain @ C_P).real.max() < -delta * (1 - 1e-6)
    # sol.poles: the closed loop's 6 poles at r_min, r = 0 and r_max, in that order
    expected = [np.linalg.eigvals(A0_P + r * S_TP + sol.gain @ C_P) for r in (-r_max, 0.0, r_max)]
    assert sol.poles.shape == (18,)
    for got, want in zip(np.split(sol.poles, 3), expected):
        np.testing.assert_allclose(np.sort_complex(got), np.sort_complex(want), rtol=1e-9, atol=1e-9)


@pytest.fixture
def uncached_lmis():
    """Solve afresh, and leave no solution obtained under other solver settings in the caches."""
    for f in (rotational_design, positional_design):
        f.cache_clear()
    yield
    for f in (rotational_design, positional_design):
        f.cache_clear()


@pytest.mark.parametrize("problem", ["rotational", "positional_noiseless", "positional_noisy"])
def test_gains_do_not_depend_on_where_the_solver_stops(problem, monkeypatch, uncached_lmis):
    """With the objective beta + mu tr(P) the optimum is attained: CLARABEL's default tolerances and 1e-11 give
    the same gains (with mu = 0 they moved by 60 %, and by 5-17 % between two CPUs)."""
    from marinebench.design import lmi

    def solve():
        rotational_design.cache_clear()
        positional_design.cache_clear()
        if problem == "rotational":
            return rotational_design(0.5, 50.0).gain
        return positional_design(0.05, 1.0, 0.0 if problem == "positional_noiseless" else 1.0, -0.8727, 0.8727, 50.0).gain

    default = solve()
    monkeypatch.setattr(lmi, "SOLVER_OPTIONS", {"tol_gap_abs": 1e-11, "tol_gap_rel": 1e-11, "tol_feas": 1e-11, "max_iter": 1000})
    tight = solve()
    # the cross-axis entries of L_pz are zero to the solver's accuracy, about 1e-6 of the largest gain (8e-4 of
    # 808 at 1e-11 with the floors' CLARABEL 0.7 on an AVX2 host): compared at 1e-5 of it, the others to 1e-3
    np.testing.assert_allclose(default, tight, rtol=1e-3, atol=1e-5 * np.abs(tight).max())


def test_frozen_heading_poles_equal_transformed_poles():
    """T_p is a similarity at frozen psi: eig(A_p(psi) - L_p(psi) C_p) = eig(A0 + L_pz C_p)."""
    L_pz = positional_design(1.2, 1.0, 1.0, -0.8727, 0.8727, 50.0).gain
    ref = np.sort_complex(np.linalg.eigvals(A0_P + L_pz @ C_P))
    for psi in (0.3, 1.7, -2.5):
        c, s = np.cos(psi), np.sin(psi)
        R2 = np.array([[c, -s], [s, c]])
        Ap = np.zeros((6, 6)); Ap[0:2, 2:4] = R2; Ap[2:4, 4:6] = np.eye(2)
        Tinv = np.eye(6); Tinv[0:2, 0:2] = R2
        Lp = -Tinv @ L_pz @ R2.T  # eq. (26)
        got = np.sort_complex(np.linalg.eigvals(Ap - Lp @ C_P))
        np.testing.assert_allclose(got, ref, rtol=1e-8, atol=1e-8)


def test_infeasible_lmi_raises_design_error():
    with pytest.raises(DesignError, match="infeasible"):
        positional_design(1.0, 1.0, 1.0, -5.0, 5.0, 1.2)


def test_faster_design_has_faster_poles_and_larger_bound():
    slow = design(BejaranoTuning(delta_psi1=1.2, delta_p1=1.2, k_n=1))[1]
    fast = design(BejaranoTuning(delta_psi1=2.2, delta_p1=2.2, k_n=1))[1]
    assert fast.poles.real.max() < slow.poles.real.max()
    assert fast.beta > slow.beta  # Remark 5: faster poles -> larger final error bound


def test_verify_reports_poles_outside_the_requested_region():
    """The numpy re-check is not a rubber stamp: the same solution checked against a faster decay rate, or a
    smaller disk, than it was designed for is refused, each with its reason."""
    sol = rotational_design(1.2, 50.0)
    slowest, fastest = -sol.poles.real.max(), np.abs(sol.poles).max()
    assert verify(sol, 1.2, 50.0) == []
    (too_slow,) = verify(sol, 1.05 * slowest, 50.0)
    assert "slowest pole" in too_slow
    (too_fast,) = verify(sol, 1.2, 0.95 * fastest)
    assert "fastest pole" in too_fast


def test_verify_at_its_tolerances():
    """The re-check's edges: a pole exactly at -delta + tol max(1, delta) or at |lambda| = rho (1 + 1e-4) passes, a
    P with a zero eigenvalue does not."""
    from dataclasses import replace

    sol = rotational_design(1.2, 50.0)
    delta, rho = 2.0, 10.0
    edge = np.array([-delta + 1e-6 * delta, -rho * (1 + 1e-4)])
    assert verify(replace(sol, poles=edge), delta, rho) == []
    assert verify(replace(sol, poles=edge + [1e-9, 0.0]), delta, rho)[0].startswith("slowest pole")
    assert verify(replace(sol, poles=edge - [0.0, 1e-6]), delta, rho)[0].startswith("fastest pole")
    assert verify(replace(sol, poles=np.array([-5.0]), P=np.diag([1.0, 0.0, 2.0])), delta, rho) == [
        "P is not positive definite"]
    small = np.array([-0.5 + 1e-6, -0.6])  # below delta = 1 the slack is tol itself
    assert verify(replace(sol, poles=small), 0.5, rho) == []


def test_tuning_defaults_are_the_papers_noiseless_choices_and_the_documented_deviations():
    """Sec. V: k_omega = 1, k_n = 0 and r_max = -r_min = 0.8727 rad/s; rho = max(50, 5 delta), mu = 1e-3 and time
    scaling from delta = 50 are this package's documented deviations (README, manifest)."""
    t = BejaranoTuning()
    assert (t.delta_psi1, t.delta_p1, t.k_omega, t.k_n, t.r_max) == (0.05, 0.05, 1.0, 0.0, 0.8727)
    assert (t.rho, t.scale_above, t.trace_weight) == (None, 50.0, 1e-3)
    assert [t.rho_for(d) for d in (0.05, 10.0, 20.0, 300.0)] == [50.0, 50.0, 100.0, 1500.0]
    assert BejaranoTuning(rho=7.0).rho_for(300.0) == 7.0


@pytest.mark.parametrize("key,ok,bad", [
    ("delta_psi1", 0.0, -0.01), ("delta_p1", 0.0, -0.01), ("k_omega", 0.0, -0.01), ("k_n", 0.0, -0.01),
    ("r_max", 0.01, 0.0), ("rho", 0.5, 0.0), ("scale_above", 0.01, 0.0), ("trace_weight", 0.0, -1e-6),
])
def test_tuning_bounds(key, ok, bad):
    """delta = 0 (Fig. 7) and k = 0 are tunings; a yaw-rate bound, disk radius or scaling threshold must be > 0."""
    lows = {"delta_psi1": 0.0, "delta_p1": 0.0} if key == "rho" else {}
    assert getattr(BejaranoTuning(**lows, **{key: ok}), key) == ok
    with pytest.raises(ValueError, match=key):
        BejaranoTuning(**lows, **{key: bad})


def test_disk_radius_must_exceed_both_decay_rates():
    for field in ("delta_psi1", "delta_p1"):
        with pytest.raises(ValueError, match="must exceed delta=2.0"):
            BejaranoTuning(**{field: 2.0}, rho=2.0)
    assert BejaranoTuning(delta_psi1=2.0, delta_p1=2.0, rho=2.01).rho == 2.01


def test_design_passes_each_tuning_setting_to_its_lmi(monkeypatch):
    """Every field of the tuning reaches the LMI problem it belongs to, each decay rate with its own disk radius."""
    from marinebench.observers import bejarano

    calls = {}
    rot = rotational_design(1.2, 50.0)
    pos = positional_design(1.2, 1.0, 1.0, -0.8727, 0.8727, 50.0)
    monkeypatch.setattr(bejarano, "rotational_design", lambda *a: calls.setdefault("rot", a) and rot)
    monkeypatch.setattr(bejarano, "positional_design", lambda *a: calls.setdefault("pos", a) and pos)
    monkeypatch.setattr(bejarano, "verify", lambda sol, d, rho: calls.setdefault("verify", []).append((sol, d, rho)))
    t = BejaranoTuning(delta_psi1=3.0, delta_p1=20.0, k_omega=2.0, k_n=0.5, r_max=0.4, scale_above=10.0, trace_weight=0.01)
    assert design(t) == (rot, pos)
    assert calls["rot"] == (3.0, 50.0, 10.0, 0.01)
    assert calls["pos"] == (20.0, 2.0, 0.5, -0.4, 0.4, 100.0, 10.0, 0.01)
    assert calls["verify"] == [(rot, 3.0, 50.0), (pos, 20.0, 100.0)]


class PanicException(BaseException):
    """Named as pyo3's ``pyo3_runtime.PanicException`` (a BaseException), which CLARABEL >= 0.9 raises on
    extreme data; older CLARABELs fail the same data without panicking, so test_cli cannot show this on every
    version."""


@pytest.mark.parametrize("raised, expected", [(PanicException("index out of bounds"), DesignError),
                                              (KeyboardInterrupt(), KeyboardInterrupt)])
def test_a_solver_panic_is_a_design_error_naming_the_design_and_ctrl_c_is_not(raised, expected, monkeypatch):
    import cvxpy as cp

    from marinebench.design.lmi import solve

    def panics(*args, **kwargs):
        raise raised

    problem = cp.Problem(cp.Minimize(cp.Variable()))
    monkeypatch.setattr(problem, "solve", panics)
    with pytest.raises(expected) as caught:
        solve(problem, "rotational LMI (delta_psi1=1.0)")
    if expected is DesignError:
        assert str(caught.value) == ("rotational LMI (delta_psi1=1.0): the solver crashed (index out of bounds); are "
                                     "the settings within a sensible range?")


@pytest.mark.parametrize("panics", [False, True])
def test_what_the_solver_writes_to_stderr_is_kept_unless_it_panicked(panics, monkeypatch, capfd):
    """Rust's panic hook writes its message (and, under RUST_BACKTRACE, 100+ lines of backtrace) to fd 2 before the
    PanicException reaches Python; the DesignError says it in one line, so that text is dropped. A solve that does
    not panic has its stderr output written back."""
    import cvxpy as cp

    from marinebench.design.lmi import solve

    def writes_to_fd2(*args, **kwargs):
        os.write(2, b"thread '<unnamed>' panicked at src/lib.rs\n")
        if panics:
            raise PanicException("Eigval error")

    problem = cp.Problem(cp.Minimize(cp.Variable()))
    monkeypatch.setattr(problem, "solve", writes_to_fd2)
    with pytest.raises(DesignError):  # a problem that solve() did not solve is not OPTIMAL either
        solve(problem, "rotational LMI (delta_psi1=1.0)")
    os.write(2, b"after\n")
    err = capfd.readouterr().err
    assert err == ("after\n" if panics else "thread '<unnamed>' panicked at src/lib.rs\nafter\n")


def test_a_crashing_design_prints_one_line_even_with_a_rust_backtrace(tmp_path):
    """End to end, in a process of its own (the panic hook writes to fd 2, which CliRunner does not see): CLARABEL
    >= 0.9 panics on a weight of 1e300 (older ones fail without a panic); either way stderr is the one error line."""
    env = {**os.environ, "RUST_BACKTRACE": "1"}
    done = subprocess.run([sys.executable, "-m", "marinebench", "validate", str(CONFIGS / "bejarano_fig7.yaml"),
                           "--set", "variants.0.observer.trace_weight=1e300"],
                          capture_output=True, text=True, env=env, cwd=tmp_path, check=False)
    assert done.returncode == 2
    assert done.stdout == ""
    assert done.stderr.startswith("error: --set: variants.0.observer: rotational LMI (delta_psi1=0.0, rho=50.0): ")
    assert done.stderr.count("\n") == 1, done.stderr


FORKED_SOLVE = """
import os, signal
from marinebench.design.lmi import positional_design
positional_design(1.2, 1.0, 1.0, -0.8727, 0.8727, 50.0)  # k_n > 0: the problem CLARABEL's parallel parts take
pid = os.fork()
if pid == 0:
    signal.alarm(60)  # a child waiting on threads the fork did not copy ends here instead of hanging
    positional_design(1.2, 1.0, 2.0, -0.8727, 0.8727, 50.0)  # a design of its own, not in the parent's cache
    os._exit(0)
os._exit(os.waitstatus_to_exitcode(os.waitpid(pid, 0)[1]))
"""


def test_a_process_forked_after_a_design_can_solve_one_of_its_own(tmp_path):
    """``--jobs`` workers are forked from the process that validated (and so designed) the variants. With CLARABEL's
    default ``max_threads`` (>= 0.10: a thread per core), the first parallel solve starts a thread pool, and a forked
    child's own solve then waited for ever (here: until its alarm killed it after 60 s); single-threaded, it solves."""
    done = subprocess.run([sys.executable, "-W", "ignore::DeprecationWarning", "-c", FORKED_SOLVE],
                          capture_output=True, text=True, cwd=tmp_path, timeout=180, check=False)
    assert done.returncode == 0, done.stderr
