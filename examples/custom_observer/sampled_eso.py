"""An observer of your own in a closed loop: a sampled-data extended state observer for Tijjani's ROV world.

Per DOF (depth z [m], yaw psi [rad]) the state is x = [eta, eta_dot, d], a triple integrator driven by the known
acceleration tau / m (m: the nominal inertia with added mass) and a constant unknown one d (the lumped
disturbance). Unlike Tijjani's CDO and the EO, which run continuously on the held sample, this one is discrete:

    predict, every engine step dt:        x <- Phi(dt) x + Gamma(dt) tau / m      (exact for a held tau)
    correct, at each new sample y_k:      x <- x + L (y_k - eta)

with L placing the poles of the per-sample error map (I - L C) Phi(h) at exp(-omega h) (a triple pole; h the
sensor's period, 50 ms for depth, 40 ms for yaw; omega a param per DOF), by Ackermann's formula for the pair
(Phi(h), C Phi(h)). The world calls ``step`` at the start of engine step k, after the samples due at k are taken
and before the controllers' command; ``tau`` is the command held over the step that just ended.

The samples at t = 0 are not used: the estimate starts where the world's CDO and EO start (``plant.initial``, the
pose plus the assumed estimation error), and the controller's first command sees it, as it sees theirs. RISE and
S+RISE keep the error of their first command in their law (e2(0)); a first correction that large (L kicks the
rate and disturbance estimates by 7 and 22 times the innovation at omega = 10) would enter it, and S+RISE fed by
this observer would then end S1 with yaw 0.19 rad off its reference (seed 0; 0.001 rad as it is).

Run it with ``marinebench run examples/custom_observer/sampled_eso.yaml``; the class follows the protocol in
marinebench/observers/custom_rov.py.
"""

import numpy as np


def transition(h: float) -> tuple[np.ndarray, np.ndarray]:
    """Phi(h), Gamma(h) of the triple integrator [eta, eta_dot, d] driven by an acceleration held over h."""
    phi = np.array([[1.0, h, h * h / 2], [0.0, 1.0, h], [0.0, 0.0, 1.0]])
    return phi, np.array([h * h / 2, h, 0.0])


def sample_gain(h: float, omega: float) -> np.ndarray:
    """L with the eigenvalues of (I - L C) Phi(h) all at exp(-omega h) (C = [1, 0, 0])."""
    phi, _ = transition(h)
    c = np.array([1.0, 0.0, 0.0])
    rows = np.array([c @ np.linalg.matrix_power(phi, j) for j in (1, 2, 3)])  # C Phi, C Phi^2, C Phi^3
    z = np.exp(-omega * h)
    p_phi = np.linalg.matrix_power(phi - z * np.eye(3), 3)  # (Phi - z I)^3, the desired characteristic polynomial
    return p_phi @ np.linalg.solve(rows, np.array([0.0, 0.0, 1.0]))


class SampledEso:
    scenario_kinds = ("rov_tracking",)
    signals = ("depth", "yaw", "depth_rate", "yaw_rate", "depth_disturbance", "yaw_disturbance")  # d: fed forward
    n_state = 6  # [z, z_dot, d_z, psi, psi_dot, d_psi]
    discrete = True

    def __init__(self, params: list[dict], plant, dt: float) -> None:
        self.omega = np.array([[float(p.get("omega_depth", 10.0)), float(p.get("omega_yaw", 10.0))] for p in params])
        if np.any(self.omega <= 0):
            raise ValueError("omega_depth and omega_yaw must be positive")
        self.every = [max(1, round(h / dt)) for h in plant.sample_periods]  # engine steps per sample, per DOF
        self.gain = np.array([[sample_gain(h, w) for h, w in zip(plant.sample_periods, row)] for row in self.omega])
        self.phi, self.gamma = transition(dt)
        self.inertia, self.start = plant.inertia, plant.initial

    def init(self) -> np.ndarray:
        x = np.zeros((len(self.omega), 2, 3))
        x[:, :, 0] = self.start  # where the world's other observers start: the pose plus the estimate offset
        return x.reshape(-1, 6)

    def step(self, xhat: np.ndarray, y: np.ndarray, tau: np.ndarray, k: int) -> np.ndarray:
        x = xhat.reshape(-1, 2, 3)
        if k > 0:  # predict over the step that just ended, with the command held over it
            x = x @ self.phi.T + (tau / self.inertia)[:, :, None] * self.gamma
        for dof, every in enumerate(self.every):
            if k % every == 0 and k > 0:  # a new sample of this DOF (the first one: see the module's docstring)
                x[:, dof] += self.gain[:, dof] * (y[:, dof] - x[:, dof, 0])[:, None]
        return x.reshape(-1, 6)

    def outputs(self, xhat: np.ndarray) -> dict[str, np.ndarray]:
        x = xhat.reshape(-1, 2, 3)
        return {"depth": x[:, 0, 0], "yaw": x[:, 1, 0], "depth_rate": x[:, 0, 1], "yaw_rate": x[:, 1, 1],
                "depth_disturbance": x[:, 0, 2], "yaw_disturbance": x[:, 1, 2]}

    def max_rate(self) -> float:
        return 0.0  # stepped exactly, not integrated by RK4: no step limit
