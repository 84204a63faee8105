"""Dynamic-positioning world (Torben et al. Sec. IV-B): MSS supply vessel in JONSWAP waves, disturbance
events, Gauss-Markov GNSS/heading errors sampled at Ts with hold, and a notch filter per channel.

Plant state ``x = [eta(3), nu(3), b(3)]`` (b: slowly varying NED bias load, force units). The observer
sees ``y = notch(sample_hold(eta_LF + eta_WF + v_GM))``: the discrete DP observers the held update of each
step, continuous-time ones (Bejarano's, Liu's) by default the last two updates joined linearly
(``sensors.continuous_feed``). Truth for the KPI is the low-frequency state
with the *total* unmodelled load as bias: ``b_true = b + R(psi) tau_d`` (tau_d: body-frame events).

Choices where the paper is silent (all scenario parameters): model (A) of the MSS supply vessel;
open loop (tau = 0; the paper's experiments were in closed loop, its simulation is not said to be);
wave-frequency motion as JONSWAP harmonic superposition times constant motion-RAO magnitudes for one
wave direction (models.md 2b, 130 deg); the heading error is Gauss-Markov like the GNSS (eq. (48));
the notch runs at the rate at which the measurement changes (every step with ``hold: noise``, every ts
with ``hold: measurement``) with Tustin pre-warped at w0. ``hold: noise`` is the default because eq. (48)
is a model of the sensor *error*; holding the whole measurement at 1 Hz while the vessel moves at
several m/s after the impulse makes a staircase that no state of the observer model can produce, so
the finite-time reconstruction is biased and resets fire spuriously.
"""

from __future__ import annotations

from collections.abc import Collection
from typing import Annotated, ClassVar, Literal

import numpy as np
from pydantic import BaseModel, Field, ValidationError, model_validator

from marinebench.environment.waves import component_amplitudes, dnv_gamma
from marinebench.models.supply import SupplyParams, SupplyVessel, SupplyVesselParams, bis_scale
from marinebench.observers.dp import LUMPED_SIGNALS
from marinebench.scenario import ScenarioBase, stream_rngs
from marinebench.sensors.gauss_markov import gm_step
from marinebench.sensors.notch import Biquad, tustin_notch
from marinebench.settings import STRICT

Vec3 = tuple[float, float, float]


class Impulse(BaseModel):
    """A rectangular body-frame load ``force`` [N, N, N m] during ``[t_start, t_start + duration)``."""

    model_config = STRICT
    kind: Literal["impulse"] = "impulse"
    t_start: float = Field(..., ge=0, description="when it starts [s]")
    duration: float = Field(..., gt=0, description="how long it lasts [s]")
    force: Vec3 = Field(..., description="[surge N, sway N, yaw N m], body frame")


class SlowLoad(BaseModel):
    """A smooth raised-cosine body-frame load: rises over ``rise`` s, holds, falls back over ``rise`` s."""

    model_config = STRICT
    kind: Literal["slow"] = "slow"
    t_start: float = Field(..., ge=0, description="when it starts to rise [s]")
    duration: float = Field(..., gt=0, description="total duration including rise and fall [s]")
    rise: float = Field(..., gt=0, description="the time to rise to force, and to fall back [s]")
    force: Vec3 = Field(..., description="the held load [surge N, sway N, yaw N m], body frame")

    @model_validator(mode="after")
    def _fits(self):
        if 2 * self.rise > self.duration:
            raise ValueError("2 * rise must not exceed duration")
        return self


Event = Annotated[Impulse | SlowLoad, Field(discriminator="kind")]


class Waves(BaseModel):
    """JONSWAP sea and wave-frequency motion by harmonic superposition with constant RAO magnitudes."""

    model_config = STRICT
    kind: Literal["jonswap"] = "jonswap"
    hs: float = Field(2.0, ge=0, description="significant wave height [m]")
    tp: float = Field(6.3, gt=0, description="peak period [s]")
    gamma: float | None = Field(3.3, gt=0, description="peak enhancement; null = DNV rule (1.87 here)")
    n_components: int = Field(40, ge=1, le=1000, description="harmonic components in the superposition")
    w_max_factor: float = Field(3.0, gt=1, description="highest frequency as a multiple of the peak")
    rao: Vec3 = Field((0.26, 0.21, 0.0148), description="|RAO| surge [m/m], sway [m/m], yaw [rad/m] at the peak (130 deg)")
    rao_rolloff: float = Field(
        2.0, ge=0, description="|RAO(w)| = |RAO| (w_p / w)^rolloff above the peak frequency w_p (0: constant); "
        "a 76 m hull does not follow short waves",
    )


class DpSensors(BaseModel):
    model_config = STRICT
    gnss_sigma: float = Field(0.1, ge=0, description="GM std [m]: 0.1 differential, 1.5 dual-band (see sigma_is)")
    heading_sigma_deg: float = Field(0.3, ge=0, description="std of the heading error [deg] (Torben Table I: 0.3)")
    heading_noise: Literal["gauss_markov", "white"] = Field(
        "gauss_markov",
        description="the heading error: 'gauss_markov' shares the GNSS model of eq. (48) (1/c, ts, sigma_is), as "
        "the paper states (Sec. IV-B); 'white' is a fresh N(0, heading_sigma^2) at every measurement update (how a "
        "gyrocompass's own noise is often simulated; an alternative, not the paper's)",
    )
    sigma_is: Literal["stationary", "driving"] = Field(
        "stationary",
        description="'stationary': sigma is the error's stationary std (a sensor's stated accuracy; driving std "
        "sigma*sqrt(1 - exp(-2 c Ts))); 'driving': sigma is rho's std in eq. (48) literally (stationary ~23.5 sigma)",
    )
    gm_time_constant: float = Field(1100.0, gt=0, description="1/c [s]")
    ts: float = Field(1.0, gt=0, description="sample time of the Gauss-Markov errors, eq. (48) [s]")
    hold: Literal["noise", "measurement"] = Field(
        "noise",
        description="'noise': the GM error is sampled every ts and held, the pose is measured every step "
        "(default); 'measurement': the whole measurement is sampled every ts and held",
    )
    between_samples: Literal["hold", "linear"] = Field(
        "hold",
        description="the Gauss-Markov error between its ts samples (with hold='noise'): 'hold' (staircase) or "
        "'linear' (interpolated: the same eq. (48) samples, a continuous error as a physical drift is)",
    )
    notch: bool = Field(True, description="pass each measured channel through the notch filter of Torben eq. (49) "
                        "(notch_w0, notch_wc) before the observers see it")
    notch_w0: float = Field(1.0, gt=0, description="notch centre frequency [rad/s]")
    notch_wc: float = Field(0.5, gt=0, description="notch width [rad/s]")
    continuous_feed: Literal["foh", "hold"] = Field(
        "foh",
        description="what continuous-time observers (bejarano, liu_eso) see between measurement updates: 'foh' "
        "interpolates linearly between the last two (a one-update delay, causal), 'hold' the staircase. The DP "
        "observers are discrete and always take the held sample",
    )


class DpInitial(BaseModel):
    model_config = STRICT
    eta: Vec3 = Field((0.0, 0.0, 0.0), description="eta(0) = [north, east, heading] [m, m, rad]")
    nu: Vec3 = Field((0.0, 0.0, 0.0), description="nu(0) = [u, v, r] [m/s, m/s, rad/s]")
    bias: Vec3 = Field((0.0, 0.0, 0.0), description="slowly varying bias (current) load, NED [N, N, N m]")


class DpScenario(ScenarioBase):
    """A DP station-keeping world (Torben et al.)."""

    kind: Literal["dp_supply"] = "dp_supply"
    SIGNALS: ClassVar[dict[str, str]] = {
        "x": "north position [m]", "y": "east position [m]", "psi": "heading [rad]",
        "b_x": "bias load, north [N] (the truth adds the events' loads)", "b_y": "bias load, east [N]",
        "b_n": "bias load, yaw [N m]", "u": "surge velocity [m/s]", "v": "sway velocity [m/s]", "r": "yaw rate [rad/s]",
        "sigma_u": "lumped disturbance of surge, Bejarano eq. (6), on the observers' design model [m/s²] (when an "
                   "experiment asks for it or runs bejarano or liu_eso)",
        "sigma_v": "the same of sway [m/s²]", "sigma_r": "the same of yaw [rad/s²]"}
    vessel: SupplyParams = Field(default_factory=SupplyVesselParams, description="the plant (simulated vessel)")
    design_vessel: SupplyParams | None = Field(
        None, description="the vessel model (M, D, L) the observers are designed and run on; default: the plant's. "
        "A different one (e.g. plant supply_shipx_lf, design supply_dp_linear) simulates model mismatch",
    )
    initial: DpInitial = Field(default_factory=DpInitial, description="the initial pose, velocities and bias")
    bias_rate: Vec3 = Field((0.0, 0.0, 0.0), description="constant drift of the bias load [N/s, N/s, N m/s]")
    events: list[Event] = Field(default_factory=list, description="loads on the vessel at given times (Fig. 1's "
                                "impulse)")
    waves: Waves | None = Field(default_factory=Waves, description="the sea state (null: calm water)")
    sensors: DpSensors = Field(default_factory=DpSensors, description="GNSS and heading measurements and their "
                               "filtering")
    dt: float = Field(0.05, gt=0, description="integration and control step [s] (Torben: 0.05 s)")

    @model_validator(mode="after")
    def _sensor_grid(self):
        self.require_multiple_of_dt(self.sensors.ts, "sensors.ts")
        return self

    @property
    def model(self) -> SupplyParams:
        """The observers' design model: ``design_vessel``, or the plant's own."""
        return self.design_vessel if self.design_vessel is not None else self.vessel

    def per_run_defaults(self) -> dict[str, float]:
        """Per-run world keys: the GNSS and heading noise levels (e.g. Torben's differential and dual-band GNSS), the
        Gauss-Markov errors' time constant 1/c, and the significant wave height (0 without ``waves``)."""
        return {"gnss_sigma": self.sensors.gnss_sigma, "heading_sigma_deg": self.sensors.heading_sigma_deg,
                "gm_time_constant": self.sensors.gm_time_constant, "hs": self.waves.hs if self.waves is not None else 0.0}

    def check_per_run(self, world: dict[str, float]) -> None:
        """The per-run settings, bounded as the scenario's own ``sensors`` and ``waves`` fields are; a sea state needs
        the scenario's ``waves`` (its period, spectrum and RAOs)."""
        sensors = {key: value for key, value in world.items() if key != "hs"}
        DpSensors.model_validate(self.sensors.model_dump() | sensors)
        if "hs" in world:
            if self.waves is None and world["hs"] > 0:  # a ValidationError at key hs, as the bounds' are
                raise ValidationError.from_exception_data("DpScenario", [{
                    "type": "value_error", "loc": ("hs",), "input": world["hs"], "ctx": {"error": (
                        "this world has no waves (waves: null): give it a sea state, scenario.waves, whose hs a run "
                        "may change")}}])
            Waves.model_validate((self.waves or Waves()).model_dump() | {"hs": world["hs"]})

    def assumptions(self, per_run: Collection[str] = ()) -> list[str]:
        """A model mismatch: the observers run on another vessel model than the plant."""
        if self.design_vessel in (None, self.vessel):
            return []
        return [f"plant {self.vessel.kind}, observers designed and run on {self.model.kind} (model mismatch)"]


class DpWorld:
    """Batched DP world; run ``b`` uses seed ``seed_of_run[b]`` and per-run sensor overrides."""

    def __init__(self, sc: DpScenario, root_seed: int, seed_of_run: np.ndarray, per_run: dict[str, np.ndarray] | None = None,
                 lumped: bool = False):
        self.sc = sc
        self.plant = SupplyVessel(sc.vessel)
        # truth of the lumped disturbance (Bejarano eq. (6)) only when an observer estimates it: it costs one
        # more plant evaluation per step
        self.design_Minv = SupplyVessel(sc.model).Minv if lumped else None
        self.scale = bis_scale(sc.vessel)
        B = len(seed_of_run)
        seeds = sorted({int(s) for s in seed_of_run})
        where = np.searchsorted(seeds, seed_of_run)
        s, own = sc.sensors, sc.per_run_values(per_run, B)
        gnss, heading = own["gnss_sigma"], np.deg2rad(own["heading_sigma_deg"])
        self.sigma = np.stack([gnss, gnss, heading], axis=1)  # (B, 3) GM driving std
        time_constant = own["gm_time_constant"][:, None]  # (B, 1): 1/c per run
        if s.sigma_is == "stationary":
            self.sigma = self.sigma * np.sqrt(1.0 - np.exp(-2.0 * s.ts / time_constant))
        self.every = round(s.ts / sc.dt)
        n_samples = int(np.ceil(sc.horizon / s.ts)) + 1
        # standard-normal GM draws, one stream per seed: (B, n_samples, 3)
        normals = np.array([g.standard_normal((n_samples + 1, 3)) for g in stream_rngs(root_seed, seeds, "gauss_markov")])
        self.normals = normals[where]
        # start in the stationary distribution for 'stationary' (eq. (48) with v[0] = 0 for 'driving')
        self.gm = np.zeros((B, 3))
        if s.sigma_is == "stationary":
            first = np.array([g.standard_normal(3) for g in stream_rngs(root_seed, seeds, "gauss_markov_initial")])
            self.gm = first[where] * np.stack([gnss, gnss, heading], axis=1)
        self.c = 1.0 / time_constant
        self.white = None
        if s.heading_noise == "white":  # white heading error: standard normals per seed and step, scaled per run
            n_steps = round(sc.horizon / sc.dt) + 1
            draws = np.array([g.standard_normal(n_steps) for g in stream_rngs(root_seed, seeds, "heading_white")])
            self.white = (draws, where, heading)
            self.sigma[:, 2] = 0.0  # no Gauss-Markov heading error
            self.gm[:, 2] = 0.0
        self.wave = self._sea(sc.waves, own["hs"], root_seed, seeds, where)
        self.filter_every = self.every if s.hold == "measurement" else 1
        self.interpolate = s.hold == "noise" and s.between_samples == "linear"
        self.gm_next = self.gm  # the next eq. (48) sample, for 'linear' (drawn at each sample instant)
        b, a = tustin_notch(s.notch_w0, s.notch_wc, self.filter_every * sc.dt)
        self.notch = Biquad(b, a, (B, 3)) if s.notch else None
        self.x0 = np.tile(np.array(sc.initial.eta + sc.initial.nu + sc.initial.bias, dtype=float), (B, 1))
        self.y = np.zeros((B, 3))
        self.y_prev = self.y  # the measurement update before, for 'foh'
        self.t_update = 0.0
        self.update_dt = self.filter_every * sc.dt
        self.tau = np.zeros((B, 3))
        self._bias_rate = np.tile(np.array(sc.bias_rate, dtype=float), (B, 1))
        self._sample = 0

    @staticmethod
    def _sea(w: Waves | None, hs: np.ndarray, root_seed: int, seeds: list[int], where: np.ndarray) -> tuple | None:
        """The wave-frequency motion's components: frequencies on an equally spaced grid, amplitudes per sea state
        (each distinct per-run ``hs``), phases per seed (runs of a seed share its sea); None in calm water."""
        if w is None or not (hs > 0).any():
            return None
        w0 = 2 * np.pi / w.tp
        dw = w.w_max_factor * w0 / w.n_components
        omega = dw * (np.arange(w.n_components) + 0.5)
        states, state = np.unique(hs, return_inverse=True)
        amp = np.array([component_amplitudes(omega, np.full_like(omega, dw), h, w.tp,
                                             w.gamma if w.gamma is not None else dnv_gamma(h, w.tp)) if h > 0
                        else np.zeros_like(omega) for h in states])
        amp = amp * np.minimum(1.0, (w0 / omega) ** w.rao_rolloff)  # frequency shape of the motion RAO
        phases = np.array([g.uniform(0, 2 * np.pi, w.n_components) for g in stream_rngs(root_seed, seeds, "waves")])
        return omega, amp, phases, (state, where), np.array(w.rao)

    def wave_motion(self, t: float) -> np.ndarray:
        """eta_WF(t) ``(B, 3)``."""
        if self.wave is None:
            return np.zeros_like(self.y)
        omega, amp, phases, (state, where), rao = self.wave
        zeta = (amp[:, None, :] * np.cos(omega * t + phases)[None]).sum(axis=2)[state, where]  # per sea and seed: (B,)
        return zeta[:, None] * rao[None, :]

    def events(self, t: float) -> np.ndarray:
        """Body-frame disturbance load tau_d(t), the same for every run, ``(3,)``."""
        f = np.zeros(3)
        for e in self.sc.events:
            if e.kind == "impulse":
                if e.t_start <= t < e.t_start + e.duration:
                    f += e.force
            else:
                tau = t - e.t_start
                if 0 <= tau <= e.duration:
                    ramp = min(tau, e.duration - tau, e.rise) / e.rise
                    f += np.array(e.force) * 0.5 * (1 - np.cos(np.pi * ramp))
        return f

    def begin_step(self, k: int, t: float, x: np.ndarray) -> None:
        """Update the GM errors every ``ts`` and the (filtered) measurement at its rate; hold in between."""
        s = self.sc.sensors
        if k % self.every == 0:
            if k > 0:
                self.gm = self.gm_next if self.interpolate else gm_step(self.gm, self.sigma, self.c, s.ts, self.normals[:, self._sample])
            self._sample += 1
            if self.interpolate:  # the next eq. (48) sample, drawn from the same stream as 'hold' would
                self.gm_next = gm_step(self.gm, self.sigma, self.c, s.ts, self.normals[:, self._sample])
        if k % self.filter_every:
            return
        error = self.gm
        if self.interpolate:
            error = self.gm + (k % self.every) / self.every * (self.gm_next - self.gm)
        raw = x[:, :3] + self.wave_motion(t) + error  # heading kept continuous (unwrapped) for the filter
        if self.white is not None:
            draws, where, std = self.white
            raw[:, 2] += std * draws[where, k]
        if self.notch is not None and k == 0:
            self.notch.reset_to(raw)
        y = self.notch(raw) if self.notch is not None else raw
        self.y_prev, self.y, self.t_update = (y if k == 0 else self.y), y, t

    def derivative(self, t: float, x: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Plant derivative, and the measurement as continuous-time observers see it (``continuous_feed``)."""
        y = self.y
        if self.sc.sensors.continuous_feed == "foh":
            y = self.y_prev + (t - self.t_update) / self.update_dt * (self.y - self.y_prev)
        return self._plant_rate(t, x), y, self.tau

    def _plant_rate(self, t: float, x: np.ndarray) -> np.ndarray:
        tau_d = np.broadcast_to(self.events(t), self.tau.shape)
        return self.plant.derivative(x, self.tau, tau_d, self._bias_rate)

    def sampled(self, t: float, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The held measurement and the known input for discrete observers, at the start of a step."""
        return self.y, self.tau

    def truth(self, t: float, x: np.ndarray) -> dict[str, np.ndarray]:
        psi = x[:, 2]
        c, s = np.cos(psi), np.sin(psi)
        fd = self.events(t)
        bx = x[:, 6] + c * fd[0] - s * fd[1]
        by = x[:, 7] + s * fd[0] + c * fd[1]
        bn = x[:, 8] + fd[2]
        out = {"x": x[:, 0], "y": x[:, 1], "psi": psi, "b_x": bx, "b_y": by, "b_n": bn,
               "u": x[:, 3], "v": x[:, 4], "r": x[:, 5]}
        if self.design_Minv is not None:
            out.update(zip(LUMPED_SIGNALS, self.lumped_disturbance(t, x).T))
        return out

    def lumped_disturbance(self, t: float, x: np.ndarray) -> np.ndarray:
        """sigma = nu_dot - M^-1 tau ``(B, 3)`` with the observers' design M (Bejarano eq. (6)): everything in
        the body-frame acceleration that the known input does not explain (damping, bias, events, and the
        plant-vs-design-model error)."""
        nu_dot = self._plant_rate(t, x)[:, 3:6]
        return nu_dot - self.tau @ self.design_Minv.T
