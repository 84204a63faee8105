"""Observers of the closed-loop ROV world (Tijjani et al.): the CDO of eq. (38) and the extended high-gain
observer EO (Chowdhury et al. 2022), one 3-state chain per DOF ``x_hat = [eta, eta_dot, delta*]`` with
``A = [[0,1,0],[0,0,1],[0,0,0]]``, ``B u = tau / m_hat`` (nominal inertia with added mass), ``C = [1 0 0]``.

CDO:  x_hat' = A x_hat + B u + Delta_theta K* (w - C x_hat),  w' = x_hat_2 + K_w (w - x_hat_1),
      w(t_k) = y(t_k) at each sample of that DOF's sensor (the inter-sample output predictor).
EO:   x_hat' = A x_hat + B u + [a1/eps, a2/eps^2, a3/eps^3] (y_held - x_hat_1).
Gains: ``marinebench.design.cdo`` (LMI (40), (39), the per-sample check).
"""

from __future__ import annotations

from typing import Any, ClassVar, Literal

import numpy as np
from pydantic import BaseModel, Field, model_validator

from marinebench.settings import STRICT, over


def chain_rhs(x_hat: np.ndarray, acc: np.ndarray, gain: np.ndarray, innovation: np.ndarray) -> np.ndarray:
    """``A x_hat + B u + gain * innovation`` for chains ``x_hat (B, n_dof, 3)``, ``acc = B u (B, n_dof)``."""
    flow = np.stack([x_hat[..., 1], x_hat[..., 2] + acc, np.zeros_like(acc)], axis=-1)
    return flow + gain * innovation[..., None]


class CdoParams(BaseModel):
    """Continuous-discrete observer of Tijjani eq. (38), one 3-state chain per DOF (baselines.md s.9).

    x_hat' = A x_hat + B u + Delta_theta K* (w - C x_hat),  w' = x_hat_2 + K_w (w - x_hat_1),
    w(t_k) = y(t_k) at each sample of that DOF's sensor (inter-sample output predictor).
    K*: Table II gives one scalar per DOF where the theory needs a 3-vector, and no literal reading is stable for
    both DOFs (baselines.md 9.4). 'lmi' solves LMI (40) with a decay rate ``lmi_decay`` (design/cdo.py; the
    paper: "the tuned parameters of the proposed observer were obtained based on LMI"); 'binomial' is
    [3, 3, 1]; or give the vector.
    """

    model_config = STRICT
    theta: float = Field(24.39, gt=0, description="theta (Table II)")
    k_w: float = Field(0.1, description="K_w (Table II)")
    k_star: Literal["lmi", "binomial"] | tuple[float, float, float] = Field("lmi", description="K* (see above)")
    lmi_decay: float = Field(
        0.35, gt=0, description="mu of the LMI design: normalised poles left of -mu (left of -mu theta in time). "
        "0.35 minimises the larger of the two per-sample error radii (depth 50 ms, yaw 40 ms) over mu",
    )

    def gain(self) -> tuple[float, float, float]:
        """The resolved K* (normalised, before Delta_theta)."""
        from marinebench.design.cdo import BINOMIAL, design_lmi

        if self.k_star == "lmi":
            return design_lmi(self.lmi_decay).k_star
        return BINOMIAL if self.k_star == "binomial" else self.k_star

    def injection(self) -> np.ndarray:
        """Delta_theta K* = [theta K*_1, theta^2 K*_2, theta^3 K*_3]."""
        with np.errstate(over="ignore"):
            return self.theta ** np.arange(1.0, 4.0) * np.array(self.gain())

    def max_rate(self) -> float:
        """Largest |eigenvalue| of the flow between samples (estimation error and predictor, ``sampled_flow``), for
        the engine's step check; ``inf`` if it overflows."""
        from marinebench.design.cdo import sampled_flow

        with np.errstate(over="ignore", invalid="ignore"):
            F = sampled_flow(self.injection(), self.k_w)
        return float(np.abs(np.linalg.eigvals(F)).max()) if np.isfinite(F).all() else float("inf")


class EoParams(BaseModel):
    """Extended high-gain observer (Chowdhury et al. 2022 form) on held samples; poles at -1/eps."""

    model_config = STRICT
    eps: float = Field(0.041, gt=0, description="[s] 1/theta: the CDO's nominal bandwidth")
    a: tuple[float, float, float] = Field((3.0, 3.0, 1.0), description="a1, a2, a3: gain [a1/eps, a2/eps^2, a3/eps^3] "
                                          "(s^3 + a1 s^2 + a2 s + a3 Hurwitz)")

    def gain(self) -> np.ndarray:
        """[a1/eps, a2/eps^2, a3/eps^3]."""
        with np.errstate(over="ignore", divide="ignore"):
            return np.array(self.a) / self.eps ** np.arange(1, 4)

    def max_rate(self) -> float:
        """Largest |pole|, for the engine's step check: the roots of ``x^3 + a1 x^2 + a2 x + a3`` over eps (the poles
        of ``s^3 + (a1/eps) s^2 + ...``, without forming the gain, so an extreme eps cannot overflow)."""
        return float(np.abs(np.roots([1.0, *self.a])).max() / self.eps)


class RovObserverSpec(BaseModel):
    """CDO (eq. 38) or extended high-gain observer (EO) view of a closed-loop run (rov_tracking).

    The variant's ``depth`` and ``yaw`` (and ``*_rate``) signals become that observer's estimates (error = estimate - truth), and ``depth_meas``/``yaw_meas`` its estimate at each
    sample instant against the sample (the only observation error a pool experiment can measure)."""

    KIND_DOCS: ClassVar[dict[str, str]] = {
        "cdo": "Tijjani's continuous-discrete observer (eq. 38, inter-sample predictor, K* from LMI (40)), as run in a closed loop.",
        "eo": "Extended high-gain observer of Chowdhury et al. 2022 (the Fig. 2 baseline), as run in a closed loop.",
    }
    model_config = STRICT
    kind: Literal["cdo", "eo"]
    cdo: dict[str, Any] = Field(
        default_factory=dict, description="this variant's CDO settings over the scenario's `cdo` (e.g. {lmi_decay: 0.2}); "
        "the CDO of these runs also feeds a controller with feedback 'cdo'",
    )
    eo: dict[str, Any] = Field(default_factory=dict, description="this variant's EO settings over the scenario's `eo` (e.g. {eps: 0.08})")

    @model_validator(mode="after")
    def _known_settings(self):
        over(CdoParams, {}, self.cdo, "cdo")  # checked over the defaults here, over the scenario's in resolve()
        over(EoParams, {}, self.eo, "eo")
        return self

    def resolve(self, scenario) -> tuple[CdoParams, EoParams]:
        """The CDO and EO of this variant's runs: the scenario's, with this variant's settings over them."""
        return (over(CdoParams, scenario.cdo.model_dump(), self.cdo, "cdo"),
                over(EoParams, scenario.eo.model_dump(), self.eo, "eo"))
