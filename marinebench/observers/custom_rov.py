"""Observers of your own in the closed-loop ROV world (``rov_tracking``): ``observer: {kind: custom, ...}`` in a
variant that also has a ``controller``.

The class follows the protocol of :mod:`marinebench.observers.custom` with ``"rov_tracking"`` among its
``scenario_kinds``, for two degrees of freedom, depth and yaw:

``signals``
    ``("depth", "yaw", "depth_rate", "yaw_rate")``: the estimates of eta = (z [m], psi [rad]) and of their rates,
    which the world records against the truth and a controller with ``feedback: custom`` is fed; and optionally
    ``depth_disturbance`` and/or ``yaw_disturbance``: the lumped disturbance as an acceleration [m/s^2, rad/s^2]
    (the CDO's x_hat_3: eta_ddot = tau / inertia + d), which such a controller with ``disturbance_feedforward``
    subtracts, times the nominal inertia, from its command as it does the CDO's, and the world records against its
    truth (:mod:`marinebench.rov_scenario`);
``__init__(self, params: list[dict], plant: RovObserverPlant, dt: float)``
    ``plant`` says what the built-in CDO and EO are given: the nominal inertia, each run's initial estimate, the
    sample and control periods (:class:`RovObserverPlant`);
``derivative(xhat, y, tau)`` (or ``discrete = True`` and ``step(xhat, y, tau, k)``)
    ``y`` the held sensor samples (depth [m], yaw [rad]) and ``tau`` the allocated, saturated command (heave force
    [N], yaw moment [N m]), both ``(B, 2)``, the same the CDO and EO take. A continuous observer is integrated with
    the plant by RK4 (the samples held over the step); a discrete one is stepped at the start of every engine step,
    after that step's samples are taken and before the controllers' command (which it may therefore feed).

The world runs the variant's runs as it runs those observed through the CDO or the EO (:mod:`marinebench.rov_scenario`):
the variant's ``depth``, ``yaw`` and rate signals are the class's estimates against the truth, ``depth_meas`` and
``yaw_meas`` its estimate just before each sample against the sample.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from marinebench.errors import ProtocolError
from marinebench.observers.custom import CheckedObserver, observer_class

ROV_ESTIMATES = ("depth", "yaw", "depth_rate", "yaw_rate")  # what a custom observer of the ROV world estimates
ROV_DISTURBANCES = ("depth_disturbance", "yaw_disturbance")  # and may estimate, for the feedforward (per DOF)


@dataclass(frozen=True)
class RovObserverPlant:
    """What a custom observer of a ``rov_tracking`` world is built on (its ``plant`` argument)."""

    inertia: np.ndarray  #: (2,) nominal inertia with added mass: heave [kg], yaw [kg m^2] (``B u = tau / inertia``)
    initial: np.ndarray  #: (B, 2) initial estimate of depth [m] and yaw [rad]: the pose plus the estimate offset
    sample_periods: tuple[float, float]  #: depth and attitude sample periods [s]
    control_period: float  #: the controllers' period [s]


def observer_plant(scenario, start: np.ndarray) -> RovObserverPlant:
    """The :class:`RovObserverPlant` of a ``rov_tracking`` scenario for runs starting their estimates at ``start``."""
    from marinebench.models.rov import LeonardLike

    periods = tuple(h for _, h in scenario.sample_periods())
    return RovObserverPlant(LeonardLike(scenario.vessel).inertia, np.asarray(start, dtype=float), periods,
                            scenario.control_period)


class CustomRovObservers:
    """The custom observers of a closed-loop world's runs (``observers``, one per run), their estimates starting at
    ``initial`` (B, 2): one batched instance per class (``source``), its state in the columns ``column:column + n_state``
    of the world's state, in its own runs' rows (zeros elsewhere)."""

    def __init__(self, observers: list, scenario, initial: np.ndarray, column: int) -> None:
        sources = [o.source if o is not None and o.kind == "custom" else None for o in observers]
        self.start, self.n_runs, self.groups = column, len(observers), []
        for source in dict.fromkeys(s for s in sources if s is not None):
            idx = np.array([b for b, s in enumerate(sources) if s == source], dtype=int)
            inner = observer_class(source)([observers[b].params for b in idx], observer_plant(scenario, initial[idx]),
                                           scenario.dt)
            self.groups.append((checked(inner, len(idx)), idx))
        self.width = max((obs.n_state for obs, _ in self.groups), default=0)
        self._none = np.full((self.n_runs, 2, 3), np.nan)  # the estimates of a batch without such an observer

    def _columns(self, obs: CheckedObserver) -> slice:
        return slice(self.start, self.start + obs.n_state)

    def init(self, x0: np.ndarray) -> None:
        for obs, idx in self.groups:
            x0[idx, self._columns(obs)] = obs.init()

    def derivative(self, x: np.ndarray, y: np.ndarray, tau: np.ndarray) -> np.ndarray:
        """The continuous classes' state derivatives, ``(B, width)`` (zeros for the other runs and discrete classes)."""
        out = np.zeros((x.shape[0], self.width))
        for obs, idx in self.groups:
            if not obs.discrete:
                cols = self._columns(obs)
                out[idx, : obs.n_state] = obs.derivative(x[idx, cols], y[idx], tau[idx])
        return out

    def step(self, x: np.ndarray, y: np.ndarray, tau: np.ndarray, k: int) -> None:
        """Advance the discrete classes one engine step, in place."""
        for obs, idx in self.groups:
            if obs.discrete:
                cols = self._columns(obs)
                x[idx, cols] = obs.step(x[idx, cols].copy(), y[idx], tau[idx], k)

    def estimates(self, x: np.ndarray) -> np.ndarray:
        """``(B, 2 DOF, 3)``: [estimate, rate estimate, disturbance estimate] of depth and yaw per run, laid out as the
        CDO's and EO's state; NaN for runs without a class and for the disturbances a class does not estimate."""
        if not self.groups:
            return self._none
        out = np.full((x.shape[0], 2, 3), np.nan)
        for obs, idx in self.groups:
            est = obs.outputs(x[idx, self._columns(obs)])
            for dof, name in enumerate(("depth", "yaw")):
                missing = np.full(len(idx), np.nan)
                out[idx, dof] = np.stack([est[name], est[f"{name}_rate"], est.get(f"{name}_disturbance", missing)], -1)
        return out

    def rates(self) -> np.ndarray:
        """Per run, the class's ``max_rate()`` (0 for runs without one), for the engine's step check."""
        out = np.zeros(self.n_runs)
        for obs, idx in self.groups:
            out[idx] = obs.max_rate()
        return out


def checked(inner, n_runs: int) -> CheckedObserver:
    """``inner`` checked against the protocol, its signals the ROV's estimates and optionally its disturbances (a
    :class:`ProtocolError` otherwise)."""
    obs = CheckedObserver(inner, n_runs)
    if not set(ROV_ESTIMATES) <= set(obs.signals) <= set(ROV_ESTIMATES + ROV_DISTURBANCES):
        raise ProtocolError(f"{obs.name}.signals is {obs.signals!r}: an observer of a rov_tracking world estimates "
                            f"{', '.join(ROV_ESTIMATES)} (and may estimate {' and '.join(ROV_DISTURBANCES)})")
    return obs
