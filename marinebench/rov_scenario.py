"""ROV depth/yaw tracking world (Tijjani et al.): the Leonard-like ROV in closed loop.

The controllers are part of the world: each run's controller (RISE or S+RISE, ``controllers/spec.py``) runs
every ``control_period`` on the held sensor samples (depth every 50 ms, attitude every 40 ms, Tijjani
Table I) or on the CDO/EO estimates (``observers/cdo.py``, integrated with the plant; or a custom observer's,
``observers/custom_rov.py``), and its command goes through the thrust allocation and saturation. Measurement-fed
controllers get rates by differencing the samples (default), from a gyro, or the true rate (``sensors.depth_rate``,
``sensors.yaw_rate``).

Truth signals ``depth``, ``yaw`` (and the achieved ``tau_depth``, ``tau_yaw``); the reference is exposed
as the "estimate" of ``depth`` and ``yaw`` (or, for runs observed through the CDO, the EO or a custom observer,
that observer's estimate), so the RMSE recorder gives the tracking RMSE of Table III.

``depth_disturbance``, ``yaw_disturbance``: the lumped disturbance d of the observers' model eta_ddot = tau_c / M_hat
+ d per DOF (Tijjani eq. (38), x_3; tau_c the allocated, saturated command, M_hat the nominal inertia), whose truth is
the plant's acceleration less tau_c / M_hat: the thrust's lag, the damping, the net buoyancy and the loads over
M_hat. A run observed through the CDO, the EO or a custom observer estimating it reports that observer's x_hat_3;
``*_disturbance_cdo`` and ``*_disturbance_eo`` are the two observers' in every run.
"""

from __future__ import annotations

import itertools
from collections.abc import Callable, Collection, Iterator, Mapping
from typing import ClassVar, Literal

import numpy as np
from pydantic import BaseModel, Field, create_model, model_validator

from marinebench.models.rov import LeonardLike, LeonardLikeParams
from marinebench.observers.cdo import CdoParams, EoParams, chain_rhs
from marinebench.observers.custom_rov import ROV_DISTURBANCES, CustomRovObservers
from marinebench.scenario import ScenarioBase, stream_rngs
from marinebench.sensors.gauss_markov import gm_step
from marinebench.settings import STRICT

#: est - truth pairs: each signal with what it is ("marinebench list rov_tracking")
ROV_SIGNAL_DOCS = {
    "depth": "the run's estimate of depth [m]: its observer's (observer:), else the reference (so est - truth is the "
             "tracking error)",
    "yaw": "the same of yaw [rad]", "depth_rate": "the same of the heave rate [m/s]",
    "yaw_rate": "the same of the yaw rate [rad/s]",
    "depth_meas": "the run's depth estimate at the last sample instant against that sample [m] (the observation "
                  "error a pool experiment can measure)", "yaw_meas": "the same of yaw [rad]",
    "depth_cdo": "the CDO's depth estimate, in every run [m]", "yaw_cdo": "the CDO's yaw estimate, in every run [rad]",
    "depth_eo": "the extended high-gain observer's depth estimate, in every run [m]",
    "yaw_eo": "the extended high-gain observer's yaw estimate, in every run [rad]",
    "depth_disturbance": "the run's observer's estimate of the lumped depth disturbance d = z'' - tau_c / M_hat "
                         "[m/s²] (no rows for runs whose observer has none)",
    "yaw_disturbance": "the same of yaw [rad/s²]",
    "depth_disturbance_cdo": "the CDO's estimate of it (x3), in every run [m/s²]",
    "yaw_disturbance_cdo": "the same of yaw [rad/s²]",
    "depth_disturbance_eo": "the extended high-gain observer's estimate of it, in every run [m/s²]",
    "yaw_disturbance_eo": "the same of yaw [rad/s²]"}
ROV_SIGNALS = tuple(ROV_SIGNAL_DOCS)
DISTURBANCE_SIGNALS = tuple(s for s in ROV_SIGNALS if "disturbance" in s)  # truth: one plant evaluation per step
OBSERVE = {None: 0, "cdo": 1, "eo": 2, "custom": 3}  # the estimate a run reports: the reference (none) or an observer's


def min_jerk(t: float, points: list[tuple[float, float]]) -> tuple[float, float]:
    """Reference through ``(time, value)`` waypoints: hold, then a minimum-jerk move to the next value
    ending at the next waypoint's time. Returns (value, rate)."""
    if t <= points[0][0]:
        return points[0][1], 0.0
    for (t0, a), (t1, b) in itertools.pairwise(points):
        if t < t1:
            s = (t - t0) / (t1 - t0)
            return a + (b - a) * s**3 * (10 - 15 * s + 6 * s**2), (b - a) * 30 * s**2 * (1 - s) ** 2 / (t1 - t0)
    return points[-1][1], 0.0


class Push(BaseModel):
    """An external load on the plant: ``force = [F_z (N, down), M_psi (N m)]`` during the interval."""

    model_config = STRICT
    t_start: float = Field(..., ge=0, description="when it starts [s]")
    duration: float = Field(..., gt=0, description="how long it lasts [s]")
    force: tuple[float, float] = Field(..., description="[F_z (N, down), M_psi (N m)]")


class Payload(BaseModel):
    """Scenario S2-C1: a payload of ``weight_fraction`` of the ROV's weight hangs on a thread; it rests on
    the floor (no load) while the ROV is at or below ``floor_depth``."""

    model_config = STRICT
    weight_fraction: float = Field(0.04, gt=0, description="the payload's weight as a fraction of the ROV's")
    floor_depth: float = Field(0.25, gt=0, description="[m] depth at or below which the payload rests on the floor")


class RandomLoad(BaseModel):
    """An unmodelled random load on the plant (tether, currents; Tijjani attributes its yaw errors to the
    tether's "undesired torques"): per DOF a stationary first-order Gauss-Markov process
    ``v[n+1] = a v[n] + std sqrt(1 - a^2) xi[n]``, ``a = exp(-period / time_constant)``, held for ``period``."""

    model_config = STRICT
    std: tuple[float, float] = Field(..., description="[N, N m] stationary standard deviation (depth, yaw)")
    time_constant: float = Field(2.0, gt=0, description="[s]")
    period: float = Field(0.1, gt=0, description="[s] a new value every period (a multiple of dt)")


class RovSensors(BaseModel):
    model_config = STRICT
    depth_period: float = Field(0.05, gt=0, description="[s] pressure sensor (Tijjani Table I)")
    attitude_period: float = Field(0.04, gt=0, description="[s] IMU (Tijjani Table I)")
    depth_noise: float = Field(
        0.00024, ge=0, description="[m] white noise std of the depth samples (assumed: the MS5803-02BA's stated "
        "resolution, about 2.4 Pa; docs/tijjani.md, Noise)",
    )
    yaw_noise_deg: float = Field(
        0.01, ge=0, description="[deg] white noise std of the yaw samples (calibrated: with it the S1 yaw INT of the "
        "three controllers is the size of Table III's; docs/tijjani.md, Noise)",
    )
    depth_rate: Literal["difference", "true"] = Field(
        "difference", description="heave rate fed to measurement-fed controllers: 'difference' of the last two depth "
        "samples (a pressure sensor gives no rate), or the true rate at the sample instant (idealised)",
    )
    yaw_rate: Literal["difference", "gyro", "true"] = Field(
        "difference", description="yaw rate fed to measurement-fed controllers: 'difference' of the last two yaw samples "
        "(the paper's controllers take only eta from the sensors, its CDO's output is C = [1 0 0]), the IMU 'gyro' "
        "(true rate plus gyro noise), or the true rate (idealised)",
    )
    gyro_noise_dps: float = Field(0.05, ge=0, description="[deg/s] white noise std of the gyro yaw-rate samples (assumed)")


class RovScenario(ScenarioBase):
    """A closed-loop ROV tracking world (Tijjani et al. scenarios)."""

    kind: Literal["rov_tracking"] = "rov_tracking"
    SIGNALS: ClassVar[dict[str, str]] = ROV_SIGNAL_DOCS
    vessel: LeonardLikeParams = Field(default_factory=LeonardLikeParams, description="the ROV model (an assumed "
                                      "Leonard-like stand-in)")
    depth_ref: list[tuple[float, float]] = Field(..., min_length=1, description="(t [s], depth [m]) waypoints")
    yaw_ref_deg: list[tuple[float, float]] = Field(..., min_length=1, description="(t [s], yaw [deg]) waypoints")
    sensors: RovSensors = Field(default_factory=RovSensors, description="depth and attitude sampling and noise")
    control_period: float = Field(0.01, gt=0, description="[s] controller period (assumed)")
    cdo: CdoParams = Field(default_factory=CdoParams, description="the CDO's settings (Tijjani eq. 38, LMI 40)")
    eo: EoParams = Field(default_factory=EoParams, description="the extended high-gain observer's gains")
    damping_scale: float = Field(1.0, gt=0, description="plant damping multiplier (S2-C2: 1.9)")
    buoyancy_scale: float = Field(1.0, gt=0, description="plant net-buoyancy multiplier (S2-C2: 2.0)")
    estimate_offset: tuple[float, float] = Field(
        (0.0, 0.0), description="initial error of the CDO and EO estimates [m, deg] (Fig. 2 shows convergence from one)"
    )
    payload: Payload | None = Field(None, description="S2-C1's hanging payload (null: none)")
    pushes: list[Push] = Field(default_factory=list, description="external loads at given times (S3)")
    random_load: RandomLoad | None = Field(None, description="unmodelled random load (off by default)")
    dt: float = Field(0.002, gt=0, description="integration step [s]")

    def per_run_defaults(self) -> dict[str, float]:
        """Per-run world keys (a variant's ``world:``, ``world.<key>`` sweep parameters) and this scenario's value of
        each: where the estimates start (``estimate_offset``, depth [m] and yaw [deg]), the sensor noise levels and
        the plant's mismatch multipliers (``damping_scale``, ``buoyancy_scale``: S2-C2's, or a robustness sweep's)."""
        s = self.sensors
        return {"estimate_offset_depth": self.estimate_offset[0], "estimate_offset_yaw_deg": self.estimate_offset[1],
                "depth_noise": s.depth_noise, "yaw_noise_deg": s.yaw_noise_deg, "gyro_noise_dps": s.gyro_noise_dps,
                **{key: getattr(self, key) for key in PLANT_SCALES.model_fields}}

    def initial_pose(self) -> np.ndarray:
        """(depth [m], yaw [rad]) at t = 0: the references' first points."""
        return np.array([self.depth_ref[0][1], np.deg2rad(self.yaw_ref_deg[0][1])])

    def initial_estimates(self, own: dict[str, np.ndarray]) -> np.ndarray:
        """``(B, 2)``: where each run's observers (the CDO, the EO, a custom one) start, the initial pose plus the run's
        estimate offset (``own``: the per-run world values, :meth:`per_run_values`)."""
        offset = np.stack([own["estimate_offset_depth"], np.deg2rad(own["estimate_offset_yaw_deg"])], axis=1)
        return self.initial_pose() + offset

    def check_per_run(self, world: dict[str, float]) -> None:
        """Per-run noise levels and plant multipliers are bounded as the scenario's own fields are (any finite
        offset goes)."""
        RovSensors.model_validate(self.sensors.model_dump() | {k: v for k, v in world.items() if k in RovSensors.model_fields})
        PLANT_SCALES.model_validate({k: v for k, v in world.items() if k in PLANT_SCALES.model_fields})

    def assumptions(self, per_run: Collection[str] = ()) -> list[str]:
        """The thrusters' dynamics and where the CDO's and EO's estimates start (Fig. 2's verdicts depend on it; the
        paper gives neither), or that the variants set the start per run (``per_run``: the keys they set)."""
        lag = self.vessel.thrust_time_constant
        thrust = (f"each thruster's thrust lags its command, first order with T = {lag:g} s" if lag > 0 else
                  "the thrust follows the command at once")
        depth, yaw = self.estimate_offset
        where = "at the true depth and yaw" if depth == yaw == 0 else f"{depth:g} m and {yaw:g} deg from the true depth and yaw"
        varied = [key for key in ("estimate_offset_depth", "estimate_offset_yaw_deg") if key in per_run]
        per_variant = f", except in the runs whose variant's world: sets {' or '.join(varied)}" if varied else ""
        start = f"the CDO's and EO's estimates start {where} (estimate_offset; no initial estimation error is given in the paper)"
        return [f"{thrust} (vessel.thrust_time_constant; the paper gives no thruster dynamics)", start + per_variant]

    def cdo_design(self, cdo: CdoParams | None = None) -> dict:
        """K*, the LMI (40) residual and, per DOF, (39) and the per-sample radius of ``cdo`` (default: the
        scenario's); raises DesignError."""
        from marinebench.design.cdo import check, design_lmi, sample_noise_gain

        c = self.cdo if cdo is None else cdo
        k = c.gain()
        out = {"k_star": list(k), "mode": c.k_star if isinstance(c.k_star, str) else "given", "theta": c.theta, "k_w": c.k_w}
        if c.k_star == "lmi":
            d = design_lmi(c.lmi_decay)
            out.update(lmi_decay=c.lmi_decay, lmi40_max_eig=d.lmi_max_eig,
                       poles=sorted((c.theta * d.poles_normalised.real).round(3).tolist()))
        for dof, h in self.sample_periods():
            out[f"sampled_radius_{dof}"] = round(check(k, c.theta, c.k_w, h, dof), 4)
            out[f"noise_gain_{dof}"] = round(sample_noise_gain(c.injection(), h, c.k_w), 4)
        return out

    def eo_design(self, eo: EoParams | None = None) -> dict:
        """The EO's injection gain, poles and, per DOF, its sample-noise gain (held samples, no predictor)."""
        from marinebench.design.cdo import sample_noise_gain

        e = self.eo if eo is None else eo
        gain = e.gain()
        out = {"eps": e.eps, "a": list(e.a), "gain": gain.round(4).tolist(),
               "poles": sorted(np.roots([1.0, *gain]).real.round(3).tolist())}
        for dof, h in self.sample_periods():
            out[f"noise_gain_{dof}"] = round(sample_noise_gain(gain, h, predictor=False), 4)
        return out

    def sample_periods(self) -> tuple[tuple[str, float], ...]:
        """(DOF, sensor period) in the state's DOF order: depth (pressure sensor), yaw (IMU)."""
        return (("depth", self.sensors.depth_period), ("yaw", self.sensors.attitude_period))

    @model_validator(mode="after")
    def _sample_grid(self):
        self.require_multiple_of_dt(self.sensors.depth_period, "sensors.depth_period")
        self.require_multiple_of_dt(self.sensors.attitude_period, "sensors.attitude_period")
        self.require_multiple_of_dt(self.control_period, "control_period")
        if self.random_load is not None:
            self.require_multiple_of_dt(self.random_load.period, "random_load.period")
        return self


# the per-run plant multipliers, each checked as the scenario's field is (an error's loc names it)
PLANT_SCALES = create_model("PlantScales", **{key: (float, RovScenario.model_fields[key])
                                              for key in ("damping_scale", "buoyancy_scale")})


def _disturbances_estimated(observer) -> set[str]:
    """The disturbances (``depth_disturbance``, ``yaw_disturbance``) a run's observer estimates: both for the CDO and
    the EO, a custom observer's among its signals, none without an observer."""
    if observer is None:
        return set()
    return set(ROV_DISTURBANCES) & set(observer.estimated_signals()) if observer.kind == "custom" else set(ROV_DISTURBANCES)


def _per_run(params, gain) -> np.ndarray:
    """``gain(p)`` for each run's settings ``p``, computed once per distinct setting (a CDO design solves an LMI)."""
    once = {}
    for p in params:
        key = p.model_dump_json()
        if key not in once:
            once[key] = gain(p)
    return np.array([once[p.model_dump_json()] for p in params])


class OnDemand(Mapping):
    """Signals by name, some of them (``later``, computed together by ``compute()``) only when first read: a world's
    truth at a step whose recorders may not read them all (the disturbances cost a plant evaluation, about 10 % of an
    S1 run, and are read only by a metric of them, or at the traced steps). All names are keys from the start.
    ``compute`` reads the world as it is when first called: the engine's recorders read the truth within its step."""

    def __init__(self, values: dict[str, np.ndarray], later: tuple[str, ...], compute: Callable[[], dict]) -> None:
        self._values, self.later, self._compute = values, later, compute

    def __getitem__(self, name: str) -> np.ndarray:
        if name not in self._values and name in self.later:
            self._values.update(self._compute())
        return self._values[name]

    def __iter__(self) -> Iterator[str]:
        return iter([*self._values, *(name for name in self.later if name not in self._values)])

    def __len__(self) -> int:
        return len(self._values.keys() | set(self.later))


class RovWorld:
    """Batched closed loop; ``controllers`` are (ControllerSpec, run indices) groups."""

    def __init__(self, sc: RovScenario, root_seed: int, seed_of_run: np.ndarray, controllers: list,
                 observers: list | None = None, per_run: dict[str, np.ndarray] | None = None) -> None:
        self.sc, self.plant = sc, LeonardLike(sc.vessel)
        B = len(seed_of_run)
        # each run's value of the per-run world keys (a variant's `world:`), the scenario's own where none is given
        own = sc.per_run_values(per_run, B)
        seeds = sorted({int(s) for s in seed_of_run})
        where = np.searchsorted(seeds, seed_of_run)
        n = int(np.ceil(sc.horizon / sc.dt)) + 2
        draws = np.array([g.standard_normal((n, 3)) for g in stream_rngs(root_seed, seeds, "rov_sensors")])
        # unit draws per seed (runs of a seed share them; indexed per step, not copied per run) and each run's noise
        # std: depth, yaw, yaw rate
        self.draws, self.seed_index = draws, where
        self.noise_std = np.stack([own["depth_noise"], np.deg2rad(own["yaw_noise_deg"]), np.deg2rad(own["gyro_noise_dps"])], axis=1)
        # the plant's (not the observers' or controllers') damping and net buoyancy, per run (Tijjani S2-C2)
        self.damping_scale, self.net_buoyancy = own["damping_scale"], sc.vessel.net_buoyancy * own["buoyancy_scale"]
        self.random_load = np.zeros((B, 2))
        if sc.random_load is not None:
            rl = sc.random_load
            m = int(np.ceil(sc.horizon / rl.period)) + 2
            a = np.exp(-rl.period / rl.time_constant)
            xi = np.array([g.standard_normal((m, 2)) for g in stream_rngs(root_seed, seeds, "rov_random_load")])
            v = np.empty_like(xi)
            v[:, 0] = xi[:, 0]  # stationary start, then eq. (48) with the driving std giving a unit stationary std
            for n in range(1, m):
                v[:, n] = gm_step(v[:, n - 1], np.sqrt(1 - a * a), 1 / rl.time_constant, rl.period, xi[:, n])
            self.load_sequence = v * np.array(rl.std)  # (seeds, m, 2), indexed by seed_index
            self.load_every = round(rl.period / sc.dt)
        self.groups = [(spec.build(len(idx)), np.asarray(idx), spec.scale(self.plant.inertia)) for spec, idx in controllers]
        self.feedforward = [spec.feedforward_mask() for spec, _ in controllers]
        self.every = tuple(round(h / sc.dt) for _, h in sc.sample_periods())
        self.control_every = round(sc.control_period / sc.dt)
        self.m_hat = self.plant.inertia  # nominal inertia (with added mass) of each DOF
        pose, start = sc.initial_pose(), sc.initial_estimates(own)  # the observers start at the pose plus an offset
        observers = [None] * B if observers is None else observers
        # state: plant [z, psi, w, r] | CDO x_hat (2 DOF x 3) | CDO predictors w (2) | EO x_hat (2 x 3) | then the
        # state of the runs' observers of your own (kind: custom), if any
        self.custom = CustomRovObservers(observers, sc, start, column=4 + 6 + 2 + 6)
        self.x0 = np.zeros((B, self.custom.start + self.custom.width))
        self.x0[:, 0:2] = pose
        cdo, w = self.cdo_view(self.x0)
        eo = self.eo_view(self.x0)
        cdo[:, :, 0] = eo[:, :, 0] = start
        w[:] = self.x0[:, 0:2]
        self.custom.init(self.x0)
        # per run: the observer it is seen through (0 none, 1 CDO, 2 EO, 3 custom) and its CDO/EO (the scenario's,
        # or the variant's settings over them): injection gains (B, 1, 3), predictor gain K_w (B, 1)
        self.observe = np.array([OBSERVE[o.kind if o is not None else None] for o in observers])
        cdos, eos = zip(*[(sc.cdo, sc.eo) if o is None or o.kind == "custom" else o.resolve(sc) for o in observers])
        self.cdo_gain = _per_run(cdos, CdoParams.injection)[:, None]
        self.k_w = np.array([[c.k_w] for c in cdos])
        self.eo_gain = _per_run(eos, EoParams.gain)[:, None]
        self._rates = np.maximum(_per_run(cdos, CdoParams.max_rate), _per_run(eos, EoParams.max_rate))
        self._rates = np.maximum(self._rates, self.custom.rates())
        self.feedback = [spec.feedback for spec, _ in controllers]
        self.disturbances_of_runs = [_disturbances_estimated(o) for o in observers]
        self.y = self.x0[:, :2].copy()  # held samples [depth, yaw]
        self.ydot = np.zeros((B, 2))  # held rates fed to measurement-fed controllers (sensors.depth_rate, yaw_rate)
        self.at_sample = np.repeat(self.x0[None, :, :2], 4, axis=0)  # reference, CDO, EO, custom estimate at the last sample
        self.tau = np.zeros((B, 2))  # achieved thrust (after allocation, saturation and the thrusters' lag)
        self.tau_cmd = np.zeros((B, 2))  # allocated and saturated command (what the observers take as input)
        lag = sc.vessel.thrust_time_constant
        self.thrust_response = 1.0 - np.exp(-sc.dt / lag) if lag > 0 else 1.0  # per step of T dtau/dt = cmd - tau
        self.weight = sc.vessel.mass * 9.81
        self._yaw_pts = [(t, np.deg2rad(v)) for t, v in sc.yaw_ref_deg]
        self._reference_at, self._reference = None, None

    def observer_rates(self) -> np.ndarray:
        """Per run, the largest |pole| of the observers this world integrates with the plant (the CDO with its
        predictor, the EO, every run carries both; a custom observer's ``max_rate()``), for the engine's step check."""
        return self._rates

    def reference(self, t: float) -> tuple[np.ndarray, np.ndarray]:
        """The reference eta_d (depth, yaw) and its rate at ``t``, read-only: computed once per time, as a step's
        samples, command, truth and estimates all ask for it."""
        if t != self._reference_at:
            d, dd = min_jerk(t, self.sc.depth_ref)
            y, yd = min_jerk(t, self._yaw_pts)
            ref, rate = np.array([d, y]), np.array([dd, yd])
            ref.flags.writeable = rate.flags.writeable = False
            self._reference_at, self._reference = t, (ref, rate)
        return self._reference

    def loads(self, t: float, x: np.ndarray) -> np.ndarray:
        f = self.random_load.copy()
        if self.sc.payload is not None:
            hanging = x[:, 0] < self.sc.payload.floor_depth
            f[:, 0] += np.where(hanging, self.sc.payload.weight_fraction * self.weight, 0.0)
        for p in self.sc.pushes:
            if p.t_start <= t < p.t_start + p.duration:
                f += np.array(p.force)
        return f

    @staticmethod
    def cdo_view(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """CDO estimates ``(B, 2 DOF, 3)`` and predictors ``(B, 2)`` (views into the state)."""
        return x[:, 4:10].reshape(-1, 2, 3), x[:, 10:12]

    @staticmethod
    def eo_view(x: np.ndarray) -> np.ndarray:
        return x[:, 12:18].reshape(-1, 2, 3)

    def noise(self, k: int, channel: int) -> np.ndarray:
        """Each run's sensor noise at step ``k`` on ``channel`` (0 depth, 1 yaw, 2 yaw rate)."""
        return self.draws[self.seed_index, k, channel] * self.noise_std[:, channel]

    def begin_step(self, k: int, t: float, x: np.ndarray) -> None:
        if self.sc.random_load is not None:
            self.random_load = self.load_sequence[self.seed_index, k // self.load_every]
        sampled = [ch for ch, every in enumerate(self.every) if k % every == 0]
        if sampled:
            self._sample(k, t, x, sampled)
        self.custom.step(x, self.y, self.tau_cmd, k)  # discrete custom observers, between the samples and the command
        if k % self.control_every == 0:
            self._control(t, x)
        if self.thrust_response < 1.0:  # the lag one step on (exact for the held command), held over the step
            self.tau = self.tau + (self.tau_cmd - self.tau) * self.thrust_response
        else:
            self.tau = self.tau_cmd

    def _sample(self, k: int, t: float, x: np.ndarray, sampled: list[int]) -> None:
        """Take the samples due at step ``k`` (the channels ``sampled``)."""
        ref, _ = self.reference(t)
        cdo, w = self.cdo_view(x)
        eo = self.eo_view(x)
        mine = self.custom.estimates(x)
        for ch in sampled:
            self.at_sample[0, :, ch] = ref[ch]  # estimates just before the sample is taken
            self.at_sample[1, :, ch] = cdo[:, ch, 0]
            self.at_sample[2, :, ch] = eo[:, ch, 0]
            self.at_sample[3, :, ch] = mine[:, ch, 0]
            y = x[:, ch] + self.noise(k, ch)
            source = self.sc.sensors.depth_rate if ch == 0 else self.sc.sensors.yaw_rate
            if source == "difference":
                if k > 0:
                    self.ydot[:, ch] = (y - self.y[:, ch]) / (self.every[ch] * self.sc.dt)
            else:
                self.ydot[:, ch] = x[:, 2 + ch] + (self.noise(k, 2) if source == "gyro" else 0.0)
            self.y[:, ch] = y
            w[:, ch] = y  # the CDO's predictor restarts from each new sample

    def _control(self, t: float, x: np.ndarray) -> None:
        """The controllers' new commands, from the held samples or an observer's estimates (``feedback``)."""
        ref, ref_dot = self.reference(t)
        estimates = {"cdo": self.cdo_view(x)[0], "eo": self.eo_view(x)}  # [eta, eta_dot, delta] per DOF
        if "custom" in self.feedback:
            estimates["custom"] = self.custom.estimates(x)
        tau = np.zeros_like(self.tau)
        for (ctrl, idx, scale), fb, ff in zip(self.groups, self.feedback, self.feedforward):
            if fb == "measured":
                pos, vel = self.y[idx], self.ydot[idx]
            else:
                est = estimates[fb]
                pos, vel = est[idx, :, 0], est[idx, :, 1]
            tau[idx] = scale * ctrl.command(ref - pos, ref_dot - vel, self.sc.control_period)
            if ff.any():  # the DOF not fed forward may have no disturbance estimate (a custom observer's: NaN)
                tau[idx] -= np.where(ff, self.m_hat * est[idx, :, 2], 0.0)
        _, self.tau_cmd = self.plant.allocate(tau)

    def observers_derivative(self, x: np.ndarray) -> np.ndarray:
        """CDO (eq. 38 with the predictor) and EO right-hand sides, per DOF."""
        cdo, w = self.cdo_view(x)
        eo = self.eo_view(x)
        acc = self.tau_cmd / self.m_hat  # B u with the nominal inertia, u the command (the thrust is not measured)
        d_cdo = chain_rhs(cdo, acc, self.cdo_gain, w - cdo[:, :, 0])
        d_w = cdo[:, :, 1] + self.k_w * (w - cdo[:, :, 0])
        d_eo = chain_rhs(eo, acc, self.eo_gain, self.y - eo[:, :, 0])
        parts = [d_cdo.reshape(-1, 6), d_w, d_eo.reshape(-1, 6)]
        if self.custom.width:  # observers of your own
            parts.append(self.custom.derivative(x, self.y, self.tau_cmd))
        return np.concatenate(parts, axis=1)

    def derivative(self, t: float, x: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        plant = self.plant.derivative(x[:, :4], self.tau, self.loads(t, x), self.damping_scale, self.net_buoyancy)
        return np.concatenate([plant, self.observers_derivative(x)], axis=1), self.y, self.tau

    def truth(self, t: float, x: np.ndarray) -> dict[str, np.ndarray]:
        """The true signals, and the reference ``depth_ref``, ``yaw_ref`` (the tracking error is theirs less the
        truth whichever estimate a run reports: INT's start)."""
        z, psi = x[:, 0], x[:, 1]
        ref = np.broadcast_to(self.reference(t)[0][:, None], (2, z.size))
        return OnDemand({"depth": z, "yaw": psi, "depth_rate": x[:, 2], "yaw_rate": x[:, 3], "depth_ref": ref[0],
                         "yaw_ref": ref[1], "tau_depth": self.tau[:, 0], "tau_yaw": self.tau[:, 1],
                         "depth_meas": self.y[:, 0].copy(), "yaw_meas": self.y[:, 1].copy(),
                         "depth_cdo": z, "yaw_cdo": psi, "depth_eo": z, "yaw_eo": psi},
                        DISTURBANCE_SIGNALS, lambda: self._disturbances(t, x))

    def _disturbances(self, t: float, x: np.ndarray) -> dict[str, np.ndarray]:
        d = self.disturbance(t, x)
        return {name: d[:, 0 if name.startswith("depth") else 1] for name in DISTURBANCE_SIGNALS}

    def disturbance(self, t: float, x: np.ndarray) -> np.ndarray:
        """``(B, 2)``: the true lumped disturbance d = eta_ddot - tau_c / M_hat of depth [m/s^2] and yaw [rad/s^2] at
        ``t`` (the acceleration over the step that starts there: the achieved thrust held over it)."""
        acc = self.plant.derivative(x[:, :4], self.tau, self.loads(t, x), self.damping_scale, self.net_buoyancy)[:, 2:4]
        return acc - self.tau_cmd / self.m_hat

    def estimates(self, t: float, x: np.ndarray) -> dict[str, np.ndarray]:
        """Per run, the reference (so that 'est - truth' is the tracking error e1 = eta_d - eta) or, for runs
        observed through the CDO, the EO or a custom observer, that observer's estimate; ``*_meas`` the same at the
        last sample instant (before the sample) against the sample; ``*_cdo``/``*_eo`` both observers in every run."""
        ref, ref_dot = self.reference(t)
        B = x.shape[0]
        cdo, _ = self.cdo_view(x)
        eo = self.eo_view(x)
        runs = np.arange(B)
        none = np.full((B, 2), np.nan)
        picks = [np.stack([np.broadcast_to(ref, (B, 2)), np.broadcast_to(ref_dot, (B, 2)), none], -1), cdo, eo]  # by OBSERVE
        if self.custom.groups:
            picks.append(self.custom.estimates(x))
        pick = np.stack(picks)[self.observe, runs]  # (B, 2 DOF, [eta, eta_dot, d])
        meas = self.at_sample[self.observe, runs]
        return {"depth": pick[:, 0, 0], "yaw": pick[:, 1, 0], "depth_rate": pick[:, 0, 1], "yaw_rate": pick[:, 1, 1],
                "depth_meas": meas[:, 0], "yaw_meas": meas[:, 1],
                "depth_cdo": cdo[:, 0, 0], "yaw_cdo": cdo[:, 1, 0], "depth_eo": eo[:, 0, 0], "yaw_eo": eo[:, 1, 0],
                "depth_disturbance": pick[:, 0, 2], "yaw_disturbance": pick[:, 1, 2],
                "depth_disturbance_cdo": cdo[:, 0, 2], "yaw_disturbance_cdo": cdo[:, 1, 2],
                "depth_disturbance_eo": eo[:, 0, 2], "yaw_disturbance_eo": eo[:, 1, 2]}

    def signals_of_runs(self) -> list[set[str]]:
        """Per run, the signals it reports an estimate of: all but the disturbances its observer does not estimate
        (no metric rows for those)."""
        return [set(ROV_SIGNALS) - set(ROV_DISTURBANCES) | own for own in self.disturbances_of_runs]
