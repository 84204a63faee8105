"""Scenario (the *world*): vessel, initial state, excitation, disturbances, sensors, horizon, dt.

``build_world`` turns a validated scenario into a batched :class:`OpenLoopASV` for given seeds. Every
random draw of seed ``j`` comes from ``SeedSequence(root, spawn_key=(j, crc32(stream)))``, so a run's
world does not depend on the batch size, on the other variants or on the order of the streams.
"""

from __future__ import annotations

import zlib
from collections.abc import Collection
from typing import Any, ClassVar, Literal

import numpy as np
from pydantic import BaseModel, Field, ValidationInfo, field_validator, model_validator

from marinebench.batch import columns
from marinebench.environment.signals import RandomSinusoid, Signal, SinusoidBatch
from marinebench.models.cybership2 import CyberShip2, CyberShip2Params
from marinebench.sensors.noise import Noise, NoiseBatch, NoNoise
from marinebench.settings import NAME, STRICT, lax_boolean

Vec3 = tuple[float, float, float]


class Initial(BaseModel):
    model_config = STRICT
    eta: Vec3 = Field((0.0, 10.0, 0.0), description="eta(0) = [x, y, psi] [m, m, rad]")
    nu: Vec3 = Field((0.0, 0.0, 0.0), description="nu(0) = [u, v, r] [m/s, m/s, rad/s]")


class Inputs(BaseModel):
    """Open-loop control tau = [F_u, 0, tau_r] (underactuated in sway). The paper gives no ranges; the defaults are
    those of ``scenarios/cs2_noiseless.yaml`` (Table III's calibrated world, see the README's "Calibration")."""

    model_config = STRICT
    F_u: Signal = Field(default_factory=lambda: RandomSinusoid(bias=(2.0, 4.0), amplitude=(0.5, 2.0)),
                        description="surge thrust [N]")
    tau_r: Signal = Field(default_factory=lambda: RandomSinusoid(bias=(-0.1, 0.1), amplitude=(0.1, 0.3)),
                          description="yaw moment [N m]")


class Disturbances(BaseModel):
    """Environmental forces tau_w = [F_wu, F_wv, tau_wr] in the body frame. The paper gives no ranges; the defaults
    are those of ``scenarios/cs2_noiseless.yaml`` (Table III's calibrated world)."""

    model_config = STRICT
    F_wu: Signal = Field(default_factory=lambda: RandomSinusoid(bias=(-0.3, 0.3), amplitude=(0.4, 1.8), frequency=(0.1, 0.4)),
                         description="surge force [N]")
    F_wv: Signal = Field(default_factory=lambda: RandomSinusoid(bias=(-0.3, 0.3), amplitude=(0.4, 1.8), frequency=(0.1, 0.4)),
                         description="sway force [N]")
    tau_wr: Signal = Field(
        default_factory=lambda: RandomSinusoid(bias=(-0.05, 0.05), amplitude=(0.1, 0.35), frequency=(0.1, 0.4)),
        description="yaw moment [N m]",
    )


class Sensors(BaseModel):
    model_config = STRICT
    position_noise: Noise = Field(default_factory=NoNoise, description="noise on the measured x, y")


class AsvPerRun(BaseModel):
    """The open-loop ASV world's per-run settings (a variant's ``world:``, ``world.<key>`` sweeps), checked against
    the scenario named ``scenario`` (``noisy``: whether it has position noise to scale)."""

    model_config = STRICT
    scenario: str
    noisy: bool
    position_noise_scale: float = Field(
        1.0, ge=0, description="multiplies the position noise (its amplitude and bound; 0: the noise-free twin)")

    @field_validator("position_noise_scale")
    @classmethod
    def _noise_to_scale(cls, scale: float, info: ValidationInfo) -> float:
        if scale != 1.0 and not info.data["noisy"]:
            raise ValueError(f"scenario '{info.data['scenario']}' has no position noise to scale (its "
                             "sensors.position_noise is none)")
        return scale


class ScenarioBase(BaseModel):
    """What every world has: a name, a horizon and the engine step (with the checks they share)."""

    model_config = STRICT
    name: str = Field(..., pattern=NAME, description="the world's name in metrics.csv and tables")
    description: str = Field("", description="free text: what the world is")
    horizon: float = Field(..., gt=0, description="simulated time [s]")
    dt: float = Field(..., gt=0, description="integration step [s]")

    #: Steps per run above which a horizon is refused as a typo: 1e8 steps of the fastest world take hours
    #: and its per-run arrays (noise draws, references) would no longer fit in memory.
    MAX_STEPS: ClassVar[int] = 10**8
    #: The signals a metric's or a figure's ``signals:`` may name on this kind of world, each an estimate scored
    #: against the world's truth of it (est - truth), with what it is ("marinebench list <kind>"). Which of them a
    #: run has depends on its observer.
    SIGNALS: ClassVar[dict[str, str]] = {}

    @model_validator(mode="after")
    def _steps_in_range(self) -> ScenarioBase:
        # checks of the pair name both keys ('horizon|dt'): an error names the one a --set changed, else the first
        if self.dt > self.horizon:
            raise ValueError(f"dt|horizon: dt={self.dt:g} s exceeds horizon={self.horizon:g} s")
        if self.horizon / self.dt > self.MAX_STEPS:
            raise ValueError(f"horizon|dt: {self.horizon:g} s at dt={self.dt:g} s is {self.horizon / self.dt:.3g} steps "
                             f"per run; at most {self.MAX_STEPS:.0e}")
        return self

    def per_run_defaults(self) -> dict[str, float]:
        """The world settings a run may override (a variant's ``world:``, a sweep group, a ``world.<key>`` sweep
        parameter), each with this scenario's own value, which the other runs take. None by default."""
        return {}

    def per_run_values(self, per_run: dict[str, np.ndarray] | None, runs: int) -> dict[str, np.ndarray]:
        """Every per-run world key over the ``runs``: the values ``per_run`` gives (``runner.per_run_world``), else this
        scenario's own."""
        return {key: np.asarray((per_run or {}).get(key, np.full(runs, own)), dtype=float)
                for key, own in self.per_run_defaults().items()}

    def check_per_run(self, world: dict[str, float]) -> None:
        """A variant's per-run world settings (their keys are checked against :meth:`per_run_defaults`): raises
        pydantic's ValidationError for a value the world's own field would refuse. Nothing to check by default."""

    #: Settings every run of an experiment's world shares, which no run may set for itself: the time axis.
    SHARED: ClassVar[tuple[str, ...]] = ("horizon", "dt")
    #: What names the world (in metrics.csv and tables) and picks its class, which no run may set for itself either.
    IDENTITY: ClassVar[tuple[str, ...]] = ("name", "description", "kind")

    def setting(self, path: str) -> float | None:
        """The world's own value of the numeric setting at a dotted ``path`` (``waves.tp``, ``control_period``), what a
        sweep may vary, or None where there is none (no such key, a text, a list, a switch, a section set to null, a
        :data:`SHARED` setting)."""
        if path in self.SHARED + self.IDENTITY:
            return None
        section, last = _section_of(self.model_dump(), path)
        value = section.get(last) if section is not None else None
        return value if isinstance(value, int | float) and not isinstance(value, bool) else None

    def has_setting(self, path: str) -> bool:
        """Whether a run may set the setting at a dotted ``path`` for itself (in a world of its own): a key of the
        world (a number, a switch, a text, a list, a whole section) other than a :data:`SHARED` or :data:`IDENTITY`
        one."""
        section, last = _section_of(self.model_dump(), path)
        return section is not None and last in section and path not in self.SHARED + self.IDENTITY

    def null_section(self, path: str) -> str | None:
        """The section above a dotted ``path`` that this world sets to null (``waves`` for ``waves.tp`` in calm
        water), if any: why :meth:`has_setting` is False for a path that other worlds of its kind have."""
        parts, node = path.split("."), self.model_dump()
        for i, part in enumerate(parts[:-1]):
            if not isinstance(node, dict) or part not in node:
                return None
            node = node[part]
            if node is None:
                return ".".join(parts[:i + 1])
        return None

    def setting_paths(self) -> list[str]:
        """Every dotted path :meth:`has_setting` accepts down to the leaves (for error hints)."""
        def walk(node: Any, prefix: str) -> list[str]:
            if isinstance(node, dict) and node:
                return [p for key, value in node.items() for p in walk(value, f"{prefix}{key}.")]
            return [prefix[:-1]]
        return [path for path in walk(self.model_dump(), "") if path not in self.SHARED + self.IDENTITY]

    def world_settings(self, world: dict[str, Any]) -> dict[str, Any]:
        """The keys of a run's ``world:`` that are not per-run keys: settings of the world by their dotted paths, for
        which the runner builds the run a world of its own (:meth:`with_settings`)."""
        per_run = self.per_run_defaults()
        return {key: value for key, value in world.items() if key not in per_run}

    def check_world(self, world: dict[str, Any]) -> None:
        """A run's world settings: its per-run keys (:meth:`check_per_run`) and the world's settings by their paths
        (:meth:`with_settings`), bounded as the file's own values are."""
        settings = self.world_settings(world)
        self.check_per_run({key: value for key, value in world.items() if key not in settings})
        self.with_settings(settings)

    def with_settings(self, settings: dict[str, Any]) -> ScenarioBase:
        """This world with ``settings`` (dotted paths to its settings, :meth:`has_setting`) written in, checked as the
        file's own values are: raises pydantic's ValidationError, or ValueError for a path to no setting a run may
        set. A whole number where the world has an integer is written as one."""
        if not settings:
            return self
        doc = self.model_dump()
        for key in settings:
            if outer := next((p for p in settings if key.startswith(p + ".")), None):
                raise ValueError(f"{key}: inside {outer}, which these settings set too (give one or the other)")
        for key, value in settings.items():
            section, last = _section_of(doc, key)
            if null := self.null_section(key):
                raise ValueError(f"{key}: not a setting of this world, whose {null} is null")
            if section is None or last not in section or key in self.SHARED + self.IDENTITY:
                raise ValueError(f"{key}: neither a per-run key of the {self.kind} world ({', '.join(self.per_run_defaults())})"
                                 f" nor a setting of it by its dotted path (e.g. sensors.<key>; "
                                 f"{' and '.join(self.SHARED)} are every run's)")
            own = section[last]
            whole = isinstance(own, int) and not isinstance(own, bool) and isinstance(value, float) and value.is_integer()
            section[last] = int(value) if whole else value
        world = type(self).model_validate(doc)
        read = world.model_dump()
        for key, value in settings.items():  # pydantic's lax mode would take true for a number, 1 for a switch
            section, last = _section_of(read, key)
            if found := lax_boolean(value, section[last]):
                raise ValueError(f"{'.'.join(map(str, (key, *found[0])))}: {found[1]}")
        return world

    def assumptions(self, per_run: Collection[str] = ()) -> list[str]:
        """What this world's own settings assume beyond its paper, one phrase each, for the manifest (which names the
        worlds that share a phrase); ``per_run``: the per-run keys some variant sets instead. None by default."""
        return []

    def require_multiple_of_dt(self, period: float, key: str) -> None:
        """Sampled components must tick on the engine's step grid, at most once per step."""
        ratio = period / self.dt
        if abs(ratio - round(ratio)) > 1e-9 or round(ratio) < 1:
            raise ValueError(f"{key}: {period:g} s must be a multiple of dt={self.dt:g} s (one step or more)")


class Scenario(ScenarioBase):
    """An open-loop ASV world (Bejarano et al. Sec. IV)."""

    kind: Literal["open_loop_asv"] = "open_loop_asv"
    SIGNALS: ClassVar[dict[str, str]] = {
        "u": "surge velocity [m/s]", "v": "sway velocity [m/s]", "r": "yaw rate [rad/s]",
        "sigma_u": "lumped disturbance of surge, Bejarano eq. (6) [m/s²]", "sigma_v": "the same of sway [m/s²]",
        "sigma_r": "the same of yaw [rad/s²]",
        "x": "north position [m] (npo, resetting_fto: on the linear model (41))",
        "y": "east position [m]", "psi": "heading [rad]"}
    vessel: CyberShip2Params = Field(default_factory=CyberShip2Params, description="the CyberShip II model's coefficients")
    initial: Initial = Field(default_factory=Initial, description="the initial pose and velocities")
    inputs: Inputs = Field(default_factory=Inputs, description="the open-loop control forces, drawn per seed")
    disturbances: Disturbances = Field(default_factory=Disturbances, description="the environmental forces, drawn per "
                                       "seed (the lumped disturbance the observers estimate)")
    sensors: Sensors = Field(default_factory=Sensors, description="the measurement noise")

    def per_run_defaults(self) -> dict[str, float]:
        """Per-run world keys: a multiplier of the position noise (e.g. a sweep of the noise level)."""
        return {"position_noise_scale": 1.0}

    def check_per_run(self, world: dict[str, float]) -> None:
        """A noise scale is not negative, and other than 1 only where there is noise to scale."""
        AsvPerRun.model_validate({"scenario": self.name, "noisy": self.sensors.position_noise.kind != "none", **world})


def _section_of(doc: dict, path: str) -> tuple[dict | None, str]:
    """In a dumped world, the mapping that holds a dotted ``path``'s last key (None where a part on the way is not a
    mapping: no such key, a section set to null), and that key."""
    *parents, last = path.split(".")
    section: Any = doc
    for part in parents:
        section = section.get(part) if isinstance(section, dict) else None
    return (section if isinstance(section, dict) else None), last


def stream_rngs(root: int, seeds: list[int], stream: str) -> list[np.random.Generator]:
    """One generator per seed index for the named random stream."""
    key = zlib.crc32(stream.encode())
    return [np.random.default_rng(np.random.SeedSequence(root, spawn_key=(j, key))) for j in seeds]


class OpenLoopASV:
    """Batched open-loop CyberShip II world; run ``b`` uses seed ``seed_of_run[b]``."""

    def __init__(self, scenario: Scenario, root_seed: int, seed_of_run: np.ndarray,
                 per_run: dict[str, np.ndarray] | None = None) -> None:
        self.scenario = scenario
        self.plant = CyberShip2(scenario.vessel)
        seeds = sorted({int(s) for s in seed_of_run})
        where = np.searchsorted(seeds, seed_of_run)

        def signal(name: str, spec) -> SinusoidBatch:
            return spec.sample(stream_rngs(root_seed, seeds, name)).take(where)

        self.F_u = signal("F_u", scenario.inputs.F_u)
        self.tau_r = signal("tau_r", scenario.inputs.tau_r)
        self.F_wu = signal("F_wu", scenario.disturbances.F_wu)
        self.F_wv = signal("F_wv", scenario.disturbances.F_wv)
        self.tau_wr = signal("tau_wr", scenario.disturbances.tau_wr)
        noise = scenario.sensors.position_noise.sample(stream_rngs(root_seed, seeds, "position_noise"), 2)
        self.noise: NoiseBatch | None = noise.take(where) if noise is not None else None
        scale = (per_run or {}).get("position_noise_scale")  # (B,) when a variant sets it: each run's noise multiplier
        self.noise_scale = None if scale is None else np.asarray(scale, dtype=float)[:, None]
        B = len(seed_of_run)
        self.x0 = np.tile(np.array(scenario.initial.eta + scenario.initial.nu, dtype=float), (B, 1))
        self._zeros = np.zeros(B)
        self._forces_t: float | None = None

    def forces(self, t: float) -> tuple[np.ndarray, np.ndarray]:
        """Control tau and environmental tau_w at time t, each ``(B, 3)`` and read-only: the last time's are kept,
        as the engine asks twice per step for the same t (the truth and RK4's first stage; its two mid-point
        stages)."""
        if self._forces_t != t:
            tau = columns(self.F_u(t), self._zeros, self.tau_r(t))
            tau_w = columns(self.F_wu(t), self.F_wv(t), self.tau_wr(t))
            tau.flags.writeable = tau_w.flags.writeable = False  # kept for the next call: a write would corrupt it
            self._forces_t, self._forces = t, (tau, tau_w)
        return self._forces

    def measure(self, t: float, x: np.ndarray) -> np.ndarray:
        """y = eta + n (eq. 8), heading noiseless (Assumption 3)."""
        y = x[:, :3].copy()
        if self.noise is not None:
            y[:, :2] += self.noise(t) if self.noise_scale is None else self.noise_scale * self.noise(t)
        return y

    def derivative(self, t: float, x: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        tau, tau_w = self.forces(t)
        return self.plant.derivative(x, tau, tau_w), self.measure(t, x), tau

    def truth(self, t: float, x: np.ndarray) -> dict[str, np.ndarray]:
        _, tau_w = self.forces(t)
        sigma = self.plant.sigma(x[:, 3:], tau_w)
        return {
            "u": x[:, 3], "v": x[:, 4], "r": x[:, 5],
            "sigma_u": sigma[:, 0], "sigma_v": sigma[:, 1], "sigma_r": sigma[:, 2],
            "x": x[:, 0], "y": x[:, 1], "psi": x[:, 2],
        }
