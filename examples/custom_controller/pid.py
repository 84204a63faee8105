"""A controller of your own, benchmarked by marinebench: PID with a clamped integral, per DOF (depth, yaw).

    tau = kp e1 + ki int(e1) + kd e1_dot,   int(e1) clamped to +-i_max (anti-windup)

with e1 = eta_d - eta (depth down-positive [m], yaw [rad]) and e1_dot its rate, as the world feeds every controller
(from the sensor samples, or from the CDO/EO with ``feedback: cdo``). The default gains place both loops near a
double pole (depth at -2.5 rad/s on the Leonard-like 63 kg heave inertia, yaw at -4 rad/s on its 1.82 kg m^2),
with an integral to hold the +9 N net buoyancy.

Run it with ``marinebench run examples/custom_controller/pid_s1.yaml``; the contract is in
marinebench/controllers/spec.py.
"""

import numpy as np

DEFAULTS = {"depth": {"kp": 400.0, "ki": 150.0, "kd": 315.0, "i_max": 0.15},  # N/m, N/(m s), N s/m; m s
            "yaw": {"kp": 29.0, "ki": 20.0, "kd": 14.6, "i_max": 0.25}}        # N m/rad, ...; rad s


class Pid:
    def __init__(self, params: dict, batch: int) -> None:
        unknown = set(params) - set(DEFAULTS) | {f"{dof}.{k}" for dof in DEFAULTS for k in params.get(dof, {})
                                                 if k not in DEFAULTS[dof]}
        if unknown:
            raise ValueError(f"unknown PID settings {sorted(unknown)}")
        gains = {dof: {**DEFAULTS[dof], **params.get(dof, {})} for dof in DEFAULTS}
        # one column per DOF (depth, yaw)
        self.kp, self.ki, self.kd, self.i_max = (np.array([float(gains[d][k]) for d in DEFAULTS])
                                                 for k in ("kp", "ki", "kd", "i_max"))
        if min(self.kp.min(), self.ki.min(), self.kd.min(), self.i_max.min()) < 0:
            raise ValueError("PID gains and i_max must be non-negative")
        self.integral = np.zeros((batch, 2))

    def command(self, e1: np.ndarray, e1_dot: np.ndarray, h: float) -> np.ndarray:
        self.integral = np.clip(self.integral + e1 * h, -self.i_max, self.i_max)
        return self.kp * e1 + self.ki * self.integral + self.kd * e1_dot
