"""Experiment configuration: the pydantic v2 models of an experiment YAML (variants, metrics, table,
figures, sweep, engine) and their cross-checks. Reading the files (``from:``, ``--set``, profiles, error
mapping to file and key) and the preflight checks are in :mod:`marinebench.loading`.
"""

from __future__ import annotations

import re
from typing import Annotated, Any, Literal

from pydantic import (
    BaseModel,
    BeforeValidator,
    Discriminator,
    Field,
    Tag,
    WithJsonSchema,
    field_validator,
    model_validator,
)

from marinebench.claims import Claim, SweepClaim
from marinebench.controllers.spec import ControllerSpec
from marinebench.dp_scenario import DpScenario
from marinebench.observers.bejarano import BejaranoObserver, BejaranoTuning
from marinebench.observers.cdo import RovObserverSpec
from marinebench.observers.custom import CustomTuning
from marinebench.observers.dp import SIGNALS as DP_SIGNALS
from marinebench.observers.dp import DpObserver, NpoTuning, ResettingTuning
from marinebench.observers.liu_eso import LiuEsoObserver, LiuEsoTuning
from marinebench.rov_scenario import RovScenario
from marinebench.scenario import Scenario
from marinebench.settings import NAME, STRICT

ObserverTuning = Annotated[
    BejaranoTuning | LiuEsoTuning | NpoTuning | ResettingTuning | RovObserverSpec | CustomTuning, Field(discriminator="kind")
]


def _scenario_kind(v) -> str:
    return v.get("kind", "open_loop_asv") if isinstance(v, dict) else getattr(v, "kind", "open_loop_asv")


AnyScenario = Annotated[
    Annotated[Scenario, Tag("open_loop_asv")]
    | Annotated[DpScenario, Tag("dp_supply")]
    | Annotated[RovScenario, Tag("rov_tracking")],
    Discriminator(_scenario_kind),
]
DIAGNOSTICS = ("n_resets", "n_jumps", "log10_cond_mean", "cond_max")  # per-run observer diagnostics (DP observers)
SIGNALS = ("u", "v", "r", "sigma_u", "sigma_v", "sigma_r")
# What an error metric or a table covers when it names no signals: what the variants' observers estimate
# (in this order), or, for closed-loop variants, what the scenario kind tracks.
SIGNALS_OF = {"bejarano": BejaranoObserver.signals, "liu_eso": LiuEsoObserver.signals,
              "npo": DpObserver.signals, "resetting_fto": DpObserver.signals}
DEFAULT_SIGNALS = {"open_loop_asv": SIGNALS, "dp_supply": DP_SIGNALS, "rov_tracking": ("depth", "yaw")}
# The signals a world records the truth of, where it is narrower than what observers estimate: the open-loop ASV
# world has no bias (the DP observers running there are compared on velocity and sigma)
TRUTH_SIGNALS = {"open_loop_asv": SIGNALS + ("x", "y", "psi")}


def flat_settings(value: Any) -> Any:
    """A ``world:`` mapping with its nested mappings read as dotted paths: ``{waves: {tp: 8}}`` is ``{waves.tp: 8}``
    (what ``--set variants[npo].world.waves.tp=8`` writes into a world that lacks the key). A path given both ways,
    or an empty mapping, is refused; anything but a mapping is left to the type's own error."""
    if not isinstance(value, dict):
        return value
    flat: dict[str, Any] = {}
    for key, inner in value.items():
        if inner == {}:
            raise ValueError(f"'{key}': an empty mapping sets nothing (give its keys, e.g. {key}: {{<key>: <value>}})")
        leaves = flat_settings(inner).items() if isinstance(inner, dict) else [(None, inner)]
        for sub, leaf in leaves:
            path = str(key) if sub is None else f"{key}.{sub}"
            if path in flat:
                raise ValueError(f"'{path}' is given twice (as a dotted key and inside a mapping)")
            flat[path] = leaf
    return flat


WorldSettings = Annotated[
    dict[str, bool | float | str | list | None],
    BeforeValidator(flat_settings),
    WithJsonSchema({"type": "object", "additionalProperties": {"type": ["number", "boolean", "string", "array", "object", "null"]}}),
]
"""A variant's (or a sweep group's) world settings: per-run keys (numbers, checked by the preflight) and settings of
the world by their dotted paths (any value the world's own field takes), nested mappings flattened."""


class Variant(BaseModel):
    model_config = STRICT
    name: str = Field(..., pattern=NAME, description="variant name used in tables and metrics.csv")
    label: str | None = Field(None, description="legend label (default: the name)")
    observer: ObserverTuning | None = Field(None, description="the observer under test (estimation experiments)")
    controller: ControllerSpec | None = Field(None, description="the controller (closed-loop rov_tracking scenarios)")
    world: WorldSettings = Field(
        default_factory=dict, description="per-run world parameters: position_noise_scale (open_loop_asv); gnss_sigma, "
        "heading_sigma_deg, gm_time_constant, hs (dp_supply); estimate_offset_depth, estimate_offset_yaw_deg, depth_noise, yaw_noise_deg, "
        "gyro_noise_dps, damping_scale, buoyancy_scale (rov_tracking); or any other setting of the world by its "
        "dotted path (e.g. waves.tp: 8, or nested: waves: {tp: 8}; sensors.hold: measurement; design_vessel: null), run "
        "in a world of its own"
    )
    tags: dict[str, str | float] = Field(default_factory=dict, description="extra metrics.csv columns")
    scenarios: list[str] | None = Field(
        None, description="multi-scenario experiments: the scenarios this variant runs on (default: all)"
    )

    @model_validator(mode="after")
    def _one_subject(self) -> Variant:
        if self.observer is None and self.controller is None:
            raise ValueError("give an 'observer' or a 'controller'")
        if self.controller is not None and self.observer is not None and self.observer.kind not in ("cdo", "eo", "custom"):
            raise ValueError(f"a closed-loop variant can be observed through 'cdo', 'eo' or 'custom', not '{self.observer.kind}'")
        if self.controller is not None and self.controller.feedback == "custom":
            self._custom_feedback()
        return self

    def _custom_feedback(self) -> None:
        """``feedback: custom`` needs the variant's own observer, estimating the disturbances it feeds forward."""
        if getattr(self.observer, "kind", None) != "custom":
            raise ValueError("feedback 'custom' feeds the controller the variant's own observer: give observer: "
                             "{kind: custom, source: file.py:Class}")
        own = self.observer.estimated_signals()
        fed = [f"{dof}_disturbance" for dof, ff in zip(("depth", "yaw"), self.controller.feedforward_mask()) if ff]
        if missing := [s for s in fed if s not in own]:
            raise ValueError(f"disturbance_feedforward with feedback 'custom' feeds forward the observer's "
                             f"{' and '.join(missing)}, not among its signals {list(own)}")


class ErrorMetric(BaseModel):
    """Statistics of the estimation error ``est - truth`` over ``t_start <= t <= t_end``."""

    model_config = STRICT
    kind: Literal["std", "rmse", "max_abs"] = "std"
    name: str | None = Field(None, pattern=NAME, description="metric name in metrics.csv (default: the kind)")
    signals: list[str] | None = Field(
        None, min_length=1, description="default: every signal the scenario kind's observers estimate (open_loop_asv: u, v, r, "
        "sigma_u, sigma_v, sigma_r; dp_supply: x, y, psi, b_x, b_y, b_n, u, v, r; rov_tracking: depth, yaw)",
    )
    t_start: float = Field(
        5.0,
        ge=0,
        description="start of the window [s]; excludes the peaking transient from the zero initial estimate "
        "(eta(0) = [0, 10, 0] vs eta_hat(0) = 0), which the papers' 'steady-state' figures do not contain",
    )
    t_end: float | None = Field(None, gt=0, description="end of the window [s] (default: the horizon)")

    @property
    def label(self) -> str:
        return self.name or self.kind


class JTotMetric(BaseModel):
    """Torben eq. (50): J = integral of ||S^-1 (z - z_hat)|| dt over the window, S the bis units, heading
    error wrapped; signal name ``z``."""

    model_config = STRICT
    kind: Literal["j_tot"] = "j_tot"
    name: str = Field("J_tot", pattern=NAME, description="metric name in metrics.csv")
    t_start: float = Field(0.0, ge=0, description="window start [s]")
    t_end: float | None = Field(None, gt=0, description="window end [s] (default: the horizon)")
    from_fraction: float | None = Field(
        None, ge=0, lt=1, description="start the window at this fraction of the horizon (overrides t_start)"
    )

    @property
    def label(self) -> str:
        return self.name

    @property
    def signals(self) -> list[str]:
        """The one signal the KPI is recorded under (as the other metrics' ``signals``)."""
        return ["z"]

    def window(self, horizon: float) -> tuple[float, float]:
        start = self.from_fraction * horizon if self.from_fraction is not None else self.t_start
        return start, self.t_end if self.t_end is not None else horizon


class IntMetric(BaseModel):
    """Tijjani's INT = integral of tau^2 dt from the first time |e| <= tol, per DOF (signals depth, yaw); e the
    tracking error eta_d - eta, also in a variant that reports an observer's estimate."""

    model_config = STRICT
    kind: Literal["int"] = "int"
    name: str = Field("int", pattern=NAME, description="metric name in metrics.csv")
    signals: list[Literal["depth", "yaw"]] = Field(default_factory=lambda: ["depth", "yaw"],
                                                   description="the DOFs whose control input is integrated")
    tol: dict[str, float] = Field(
        default_factory=lambda: {"depth": 0.01, "yaw": 0.0175},
        description="tracking-error tolerance that marks 'reached' [m, rad]",
    )

    @property
    def label(self) -> str:
        return self.name


class RecoveryMetric(BaseModel):
    """Time to recover from each of the scenario's pushes (rov_tracking): after a push on a DOF ends, the time
    until that DOF is back within ``tol`` of where it would have been without the pushes, for good (largest
    over the pushes) [s]."""

    model_config = STRICT
    kind: Literal["recovery"] = "recovery"
    name: str = Field("recovery", pattern=NAME, description="metric name in metrics.csv")
    signals: list[Literal["depth", "yaw"]] = Field(default_factory=lambda: ["depth", "yaw"],
                                                   description="the DOFs whose recovery is timed")
    tol: dict[str, float] = Field(
        default_factory=lambda: {"depth": 0.01, "yaw": 0.0175}, description="recovered band [m, rad]"
    )
    window: float = Field(4.0, gt=0, description="[s] look this long after each push; reported if not recovered")
    against: Literal["undisturbed", "reference"] = Field(
        "undisturbed", description="undisturbed: deviation from the same run (same seed and noise) without the "
        "pushes, i.e. until the push's effect has died out; reference: the tracking error itself (a push during a "
        "manoeuvre then also counts the manoeuvre's own tracking error)",
    )

    @property
    def label(self) -> str:
        return self.name


Metric = Annotated[ErrorMetric | JTotMetric | IntMetric | RecoveryMetric, Field(discriminator="kind")]


class PaperValues(BaseModel):
    """Published numbers shown beside ours, in a column labelled as the paper's (never computed)."""

    model_config = STRICT
    source: str = Field(..., description="citation, e.g. 'Bejarano et al., Table IV'")
    values: dict[str, dict[str, float]] = Field(
        default_factory=dict,
        description="variant -> signal -> value of the table's (first) metric, shown beside ours; multi-scenario "
        "experiments: variant -> 'scenario/metric/signal' -> value",
    )
    units: dict[str, str] = Field(default_factory=dict, description="'metric/signal' (or a metric) -> the unit the paper "
                                  "reports in, noted under the table")


class Display(BaseModel):
    """How a table shows one metric of one signal: ``value * scale`` in ``unit``."""

    model_config = STRICT
    scale: float = Field(1.0, gt=0, description="our values (means and intervals) are shown multiplied by it, e.g. 100 "
                         "for m in cm; the paper's values are shown as given")
    unit: str = Field("", description="the unit shown beside the signal's name, e.g. cm")


class TableSpec(BaseModel):
    model_config = STRICT
    title: str = Field(..., description="the heading of table.md")
    metric: str = Field("std", description="a metric name (or several: rows of the same signals)")
    metrics: list[str] | None = Field(None, min_length=1, description="several metric names as columns (overrides metric)")
    signals: list[str] | None = Field(None, min_length=1, description="default: the signals of the tabulated metrics (z for j_tot)")
    paper: PaperValues | None = Field(None, description="the published values, shown beside ours in columns labelled "
                                      "as the paper's")
    relative: tuple[str, str] | None = Field(
        None, description="add a row with the % change of the first variant's means against the second's "
        "(paper values for it under '<first>_vs_<second>')",
    )
    display: dict[str, Display] = Field(
        default_factory=dict, description="'metric/signal' -> scale and unit for the table (e.g. rmse/depth: cm)"
    )

    @property
    def shown(self) -> list[str]:
        """The metrics tabulated: ``metrics``, or ``metric`` alone; the first is the one the paper's values (of a
        single-scenario experiment) and the claims without a metric are about."""
        return self.metrics or [self.metric]


class FigureSpec(BaseModel):
    """Seed 0 of the chosen variants. ``timeseries``: truth and estimates (or errors) per signal.
    ``tracking`` (closed loop, Tijjani Figs 3/5/7/9): a column per DOF with reference vs actual, tracking
    errors and control inputs."""

    model_config = STRICT
    kind: Literal["timeseries", "tracking"] = "timeseries"
    file: str = Field(..., pattern=r"^[A-Za-z0-9_.-]+\.png$", description="file name under figures/ (e.g. surge.png)")
    title: str = Field("", description="the figure's title (default: the file name)")
    signals: list[str] = Field(default_factory=lambda: ["depth", "yaw"], min_length=1,
                               description="the signals drawn, one panel each (e.g. u, v, sigma_u; depth, yaw)")
    variants: list[str] | None = Field(None, min_length=1, description="default: all variants (of this scenario)")
    scenario: str | None = Field(None, description="multi-scenario experiments: the scenario shown (default: the first)")
    error: bool = Field(True, description="add a lower panel per signal with the estimation error")
    t_range: tuple[float, float] | None = Field(None, description="[start, end] of the time axis [s] (default: the "
                                                "whole run)")
    ylim_after: float | None = Field(
        None, ge=0, description="scale the y axes to the data after this time [s] so the initial peaking does not "
        "hide the steady state (default: the first metric's t_start)",
    )

    @model_validator(mode="after")
    def _time_range(self) -> FigureSpec:
        if self.t_range is not None and not self.t_range[0] < self.t_range[1]:
            raise ValueError(f"t_range: {list(self.t_range)}: the start must be before the end")
        return self


class SweepParam(BaseModel):
    """One sweepable parameter: a setting of the swept variant, varied over ``range``.

    ``key`` is a field of the variant's observer (``k``, ``delta_p1``), a dotted path in the variant that
    starts with ``observer.`` or ``controller.`` (``observer.cdo.lmi_decay``, ``controller.yaw.alpha``), or
    ``world.<key>``, a per-run world setting of the scenario (``world.gnss_sigma``, ``world.estimate_offset_depth``)
    or any numeric setting of it by its dotted path (``world.waves.tp``, each point a world of its own);
    ``fixed`` keys read the same way."""

    model_config = STRICT
    key: str = Field(..., description="observer field (e.g. k, delta, eps_scale, delta_p1) or a dotted path in the "
                     "variant: observer.<...> or controller.<...> (e.g. controller.yaw.alpha, observer.cdo.lmi_decay), or "
                     "world.<per-run key> (e.g. world.gnss_sigma, world.estimate_offset_yaw_deg) or world.<dotted path of a "
                     "numeric world setting> (e.g. world.waves.tp)")
    range: tuple[float, float] = Field(..., description="[low, high]: the first and last values swept")
    spacing: Literal["linear", "log"] = Field("linear", description="the points' spacing over range (log: both ends "
                                              "positive)")
    fixed: dict[str, Any] = Field(default_factory=dict, description="other settings of the variant for this sweep "
                                  "(keys as for key)")
    probes: list[float] = Field(
        default_factory=list, description="values at which table.md reports the KPI (interpolated in the spacing), "
        "each beside the first probe's, e.g. k: [0, 0.7] for 'k = 0.7 against k = 0'"
    )
    trend: tuple[float, float] | None = Field(
        None, description="sub-range over which table.md reports the Spearman rank correlation of the KPI with the value"
    )
    label: str | None = Field(None, description="the figure's axis label (default: the parameter's name)")

    @model_validator(mode="after")
    def _range(self) -> SweepParam:
        lo, hi = self.range
        if lo >= hi or (self.spacing == "log" and lo <= 0):  # equal ends: n points at one value, no curve
            raise ValueError(f"bad range {self.range} for {self.spacing} spacing (from a lower to a higher value"
                             f"{', both positive' if self.spacing == 'log' else ''})")
        outside = [v for v in [*self.probes, *(self.trend or ())] if not lo <= v <= hi]
        if outside:
            raise ValueError(f"probe/trend values {outside} outside the range {self.range}")
        if repeated := sorted({v for v in self.probes if self.probes.count(v) > 1}):  # the same table row twice
            raise ValueError(f"probes {self.probes}: {repeated} given more than once")
        if self.trend is not None and self.trend[0] >= self.trend[1]:
            raise ValueError(f"trend {self.trend}: the lower end must be below the upper")
        return self

    def values(self, n: int):
        import numpy as np

        lo, hi = self.range
        return np.geomspace(lo, hi, n) if self.spacing == "log" else np.linspace(lo, hi, n)


#: Points per swept parameter at most, in a config's ``sweep.n`` and in ``sweep --n`` (a grid has the square):
#: more is a typo, not a study.
MAX_SWEEP_N = 1000


class SweepSpec(BaseModel):
    """``marinebench sweep``: one-at-a-time sweeps of a variant's parameters, per world group."""

    model_config = STRICT
    variant: str | None = Field(None, description="the variant whose settings are swept (and whose curves sweep.claims are "
                                "about); default: the first of variants, else the experiment's first (on sweep.scenario)")
    variants: list[str] | None = Field(
        None, min_length=1, description="several variants swept side by side, one curve each (default: variant alone; "
        "`sweep --variants`): every parameter's key must be a setting of each, e.g. a world.<key>",
    )
    scenario: str | None = Field(None, description="multi-scenario experiments: the scenario the sweep runs on "
                                 "(default: the variant's first)")
    params: dict[str, SweepParam] = Field(..., min_length=1, description="name -> sweepable parameter; the names are "
                                          "the arguments of marinebench sweep")
    groups: dict[str, WorldSettings] = Field(
        default_factory=lambda: {"default": {}}, description="named world settings, as a variant's world: takes them (e.g. GNSS models)"
    )
    metric: str | None = Field(None, description="metric plotted against each parameter (default: the experiment's first)")
    metrics: list[str] | None = Field(
        None, min_length=1, description="several metrics (overrides metric): a table section and a figure column each, "
        "e.g. a transient and a steady-state error to show a trade-off",
    )
    signals: list[str] | None = Field(None, min_length=1, description="the metric's signals to tabulate and plot (default: all)")
    n: int = Field(100, ge=2, le=MAX_SWEEP_N, description="points per parameter")
    claims: list[SweepClaim] = Field(default_factory=list, description="the paper's trends, checked on the curves")

    @field_validator("params", "groups")
    @classmethod
    def _names(cls, value: dict) -> dict:
        """Parameter and group names name the sweep's points (variants ``name=value``), its folder and table rows."""
        if bad := [name for name in value if not re.fullmatch(NAME, name)]:
            raise ValueError(f"name {bad[0]!r}: use letters, digits and _ . + - (it names the sweep's points and folder)")
        return value

    @model_validator(mode="after")
    def _check_claims(self) -> SweepSpec:
        for i, c in enumerate(self.claims):
            where = f"claims.{i}"
            if c.param not in self.params:
                raise ValueError(f"{where}: unknown param '{c.param}' (have: {', '.join(self.params)})")
            lo, hi = self.params[c.param].range
            values = [c.at, c.vs] if c.kind == "probe" else list(c.range) if c.kind == "trend" else []
            outside = [v for v in values if not lo <= v <= hi]
            if outside:
                raise ValueError(f"{where}: values {outside} outside {c.param}'s range {self.params[c.param].range}")
            unknown = [g for g in c.groups or [] if g not in self.groups]  # a groups claim's pair: Experiment's check
            if unknown:
                raise ValueError(f"{where}: unknown groups {unknown} (have: {', '.join(self.groups)})")
        return self

    @property
    def shown(self) -> list[str]:
        """The metrics tabulated and plotted: ``metrics``, or ``metric`` alone."""
        return self.metrics or [self.metric]

    @property
    def swept(self) -> list[str]:
        """The variants swept: ``variants``, or ``variant`` alone."""
        return self.variants or [self.variant]


class EngineOptions(BaseModel):
    model_config = STRICT
    stiffness_limit: float = Field(
        0.5, gt=0, le=2.78, description="refuse dt unless dt*|lambda|max <= this (RK4 stable below 2.78)"
    )
    check_step: bool = Field(True, description="refuse a dt too large for the observer poles (off: at your own risk)")
    trace_dt: float = Field(0.02, gt=0, description="sampling interval of the traces kept for figures [s]")
    write_traces: bool = Field(
        False, description="also write traces.csv.gz: the traces the figures draw (seed 0 of each variant, every trace_dt), "
        "one row per scenario, variant, seed, t and signal with the truth and the estimate (run --traces; a sweep keeps "
        "no traces and writes none)",
    )


class Experiment(BaseModel):
    """One paper table or figure: a scenario, variants, seeds, metrics and outputs."""

    model_config = STRICT
    name: str = Field(..., pattern=NAME, description="the experiment's name in metrics.csv, tables and manifests")
    description: str = Field("", description="free text: what the experiment reproduces")
    scenario: AnyScenario | None = Field(None, description="the world (a file path, or {from: file, overrides})")
    scenarios: dict[str, AnyScenario] | None = Field(
        None, description="several named worlds instead of one (e.g. Tijjani S1, S2-C1, ...); each variant runs on "
        "the scenarios it lists (default all); metrics.csv keeps them apart in its scenario column",
    )
    seed: int = Field(2024, ge=0, description="root seed; run seeds derive from (seed, seed index)")
    seeds: int = Field(5, ge=1, le=10000, description="Monte-Carlo runs per variant")
    variants: list[Variant] = Field(..., min_length=1, description="the observers or controllers compared, each run "
                                    "on every seed")
    metrics: list[Metric] = Field(default_factory=lambda: [ErrorMetric()], min_length=1,
                                  description="what metrics.csv holds per run (default: std of the estimation errors)")
    table: TableSpec | None = Field(None, description="table.md: our means beside the paper's values")
    figures: list[FigureSpec] = Field(default_factory=list, description="figures/*.png, drawn from seed 0")
    engine: EngineOptions = Field(default_factory=EngineOptions, description="the simulation engine's options")
    assumptions: list[str] = Field(default_factory=list, description="choices where the paper is silent")
    sweep: SweepSpec | None = Field(None, description="the parameters marinebench sweep varies on this experiment")
    claims: list[Claim] = Field(
        default_factory=list, description="the paper's claims about these runs, checked on our means: claims.md"
    )
    profiles: dict[str, list[str]] = Field(
        default_factory=dict,
        description="named lists of dotted.key=value overrides, selected with `run --profile NAME` "
        "(e.g. a quick profile for CI)",
    )

    @field_validator("scenarios", mode="before")
    @classmethod
    def _study_names(cls, value: Any) -> Any:
        """A study's keys name its scenarios (metrics.csv, tables, 'scenario/metric/signal' keys)."""
        names = [name for name in value if isinstance(name, str)] if isinstance(value, dict) else []  # else pydantic's error
        if bad := [name for name in names if not re.fullmatch(NAME, name)]:
            raise ValueError(f"name {bad[0]!r}: use letters, digits and _ . + - (it names the scenario in metrics.csv)")
        return value

    @model_validator(mode="after")
    def _cross_references(self) -> Experiment:
        if (self.scenario is None) == (self.scenarios is None):
            raise ValueError("scenario|scenarios: give exactly one of 'scenario' or 'scenarios'")
        self._fill_signals()
        self._fill_sweep()
        checked = self._check_study() if self.scenarios is not None else self._check_single()
        if self.table is not None:
            self._check_table_keys()
        return checked

    def _check_table_keys(self) -> None:
        """The table's 'metric/signal' keys (``display``, ``paper.units``) name a signal a metric records, and the
        paper's values are keyed as the table looks them up (a signal of its first metric; in a study
        'scenario/metric/signal'). Before, a misspelt key was ignored: a unit not applied, a paper value not shown."""
        table = self.table
        recorded = {name: set(self.recorded_signals(name)) for name in [m.label for m in self.metrics] + table.shown}

        def names_a_signal(key: str) -> bool:
            metric, _, signal = key.partition("/")
            return signal in recorded.get(metric, ())

        units = table.paper.units if table.paper else {}  # a note per key: of one metric's signal, or of a whole metric
        for where, bad in (("table.display", [k for k in table.display if not names_a_signal(k)]),
                           ("table.paper.units", [k for k in units if not (k in recorded or names_a_signal(k))])):
            if bad:
                raise ValueError(f"{where}: {bad} name no signal a metric records, as 'metric/signal' (e.g. "
                                 f"{table.shown[0]}/{min(recorded[table.shown[0]])})")
        for variant, values in (table.paper.values if table.paper else {}).items():
            if self.scenarios is None:
                bad = [k for k in values if k not in recorded[table.shown[0]]]
                form = f"a signal of {table.shown[0]} ({', '.join(sorted(recorded[table.shown[0]]))})"
            else:
                bad = [k for k in values if k.partition("/")[0] not in self.scenarios or not names_a_signal(k.partition("/")[2])]
                form = f"'scenario/metric/signal' (scenarios: {', '.join(self.scenarios)})"
            if bad:
                raise ValueError(f"table.paper.values: {variant}: {bad} are not keyed as the table reads them: {form}")

    def claim_metric(self, claim) -> str | None:
        if claim.metric is not None or self.table is None:
            return claim.metric
        return self.table.shown[0]

    def claim_signals(self, claim) -> list[str]:
        """The signals a claim covers: its own, or the table's."""
        return list(claim.signals or (self.table.signals if self.table is not None else None) or [])

    def metric_signals(self, label: str) -> list[str] | None:
        """The signals a metric records (None for the per-run diagnostics)."""
        m = next((m for m in self.metrics if m.label == label), None)
        if m is None:
            return None
        return list(m.signals or [])

    def recorded_signals(self, label: str) -> list[str]:
        """The signals a table, claim or sweep can show of metric ``label``: its own, or z for a per-run
        diagnostic of the DP observers (``n_jumps``, ...) and anything else that is not a metric."""
        return self.metric_signals(label) or ["z"]

    def claim_problem(self, claim) -> str | None:
        """Why a claim cannot be checked on this experiment (None: it can). Not a config error: overrides
        (``--set``) may drop a variant or metric a claim names; ``claims.md`` and ``validate`` report it."""
        unknown = [n for n in claim.variant_names if n not in {v.name for v in self.variants}]
        if unknown:
            return f"unknown variants {unknown}"
        metric = self.claim_metric(claim)
        if metric is None:
            return "no metric (give one; there is no table to take it from)"
        recorded = self.metric_signals(metric)
        if recorded is None:
            return f"metric '{metric}' is not among metrics {[m.label for m in self.metrics]}"
        signals = self.claim_signals(claim)
        if not signals:
            return "no signals (give them; there is no table to take them from)"
        missing = [s for s in signals if s not in recorded]
        if missing:
            return f"signals {missing} are not recorded by metric '{metric}'"
        if claim.scenarios is not None and not set(claim.scenarios) <= set(self.scenario_names):
            return f"unknown scenarios {sorted(set(claim.scenarios) - set(self.scenario_names))}"
        if claim.kind == "near_paper" and (self.table is None or self.table.paper is None):
            return "near_paper needs the table's paper values"
        if claim.kind == "near_paper" and self.scenarios is None and metric != (first := self.table.shown[0]):
            return f"near_paper: the paper's values (table.paper) are of the table's first metric '{first}'"
        return None

    def _fill_signals(self) -> None:
        """Default signals of error metrics and the table from the scenario kind (written out in the resolved config)."""
        worlds = [self.scenario] if self.scenario is not None else list(self.scenarios.values())
        if not worlds:
            return
        default = [s for v in self.variants if v.observer is not None and v.controller is None
                   for s in (v.observer.estimated_signals() if v.observer.kind == "custom" else SIGNALS_OF.get(v.observer.kind, ()))]
        truth = TRUTH_SIGNALS.get(worlds[0].kind)
        default = [s for s in dict.fromkeys(default) if truth is None or s in truth] or DEFAULT_SIGNALS[worlds[0].kind]
        for m in self.metrics:
            if isinstance(m, ErrorMetric) and m.signals is None:
                m.signals = list(default)
        if self.table is not None and self.table.signals is None:
            listed = set(self.table.shown)
            signals: list[str] = []
            for m in self.metrics:
                if m.label in listed:
                    signals += [s for s in m.signals if s not in signals]
            self.table.signals = signals or list(default)

    def _fill_sweep(self) -> None:
        """The sweep's defaults, written out in the resolved config: ``variant`` the first of ``variants``, else the
        experiment's first variant (the first that runs on ``sweep.scenario``); ``metric`` the first metric's name."""
        spec = self.sweep
        if spec is None:
            return
        if spec.variant is None:
            there = [v.name for v in self.variants
                     if spec.scenario is None or self.scenarios is None or v.scenarios is None or spec.scenario in v.scenarios]
            spec.variant = (spec.variants or there or [None])[0]
        if spec.metric is None and spec.metrics is None and self.metrics:
            spec.metric = self.metrics[0].label

    def _check_study(self) -> Experiment:
        """A multi-scenario experiment: check the scenario references, then each part as a single experiment."""
        if not self.scenarios:
            raise ValueError("scenarios: empty (name at least one world, or give scenario: instead)")
        have = ", ".join(self.scenarios)
        for i, v in enumerate(self.variants):
            unknown = set(v.scenarios or []) - set(self.scenarios)
            if unknown:
                raise ValueError(f"variants.{i}.scenarios: unknown scenarios {sorted(unknown)} (have: {have})")
        for f in self.figures:
            if f.scenario is not None and f.scenario not in self.scenarios:
                raise ValueError(f"figures: {f.file} names unknown scenario '{f.scenario}' (have: {have})")
        if self.sweep is not None:
            self._check_study_sweep(have)
        for name in self.scenarios:
            part = self.part(name)
            if not part.variants:
                raise ValueError(f"variants: none runs on scenario '{name}'")
            part._check_single(f"scenarios.{name}.horizon")
        return self

    def _check_study_sweep(self, have: str) -> None:
        """A study's sweep runs on one of its scenarios, with variants that run there."""
        name = self.sweep_scenario()
        if name not in self.scenarios:
            raise ValueError(f"sweep.scenario: unknown scenario '{name}' (have: {have})")
        there, known = {v.name for v in self.part(name).variants}, {v.name for v in self.variants}
        for key, names in (("variant", [self.sweep.variant]), ("variants", self.sweep.variants or [])):
            missing = [v for v in names if v in known and v not in there]  # unknown names: the scenario's check
            if missing:
                raise ValueError(f"sweep.{key}: {', '.join(map(repr, missing))} does not run on scenario '{name}'")

    @property
    def scenario_names(self) -> list[str]:
        return list(self.scenarios) if self.scenarios is not None else [self.scenario.name]

    def part(self, name: str) -> Experiment:
        """The single-scenario experiment of one named scenario: its variants, figures and table."""
        if self.scenarios is None:
            return self
        first = next(iter(self.scenarios))
        sc = self.scenarios[name].model_copy(update={"name": name})
        variants = [v for v in self.variants if v.scenarios is None or name in v.scenarios]
        keep = {v.name for v in variants}
        figures = [f.model_copy(update={"variants": [n for n in f.variants or [v.name for v in variants] if n in keep]})
                   for f in self.figures if (f.scenario or first) == name]
        table = self.table
        if table is not None and table.paper is not None:
            paper = table.paper.model_copy(update={"values": {k: v for k, v in table.paper.values.items() if k in keep}})
            table = table.model_copy(update={"paper": paper})
        sweep = self.sweep if name == self.sweep_scenario() else None
        return self.model_copy(update={"scenario": sc, "scenarios": None, "variants": variants, "figures": figures,
                                       "table": table, "sweep": sweep})

    def model_label(self) -> str:
        """The simulated vessel model(s), named in every table, claims file, figure and manifest: e.g.
        ``leonard_like`` (Tijjani's stand-in ROV, which is not the paper's robot), or for a DP world whose
        observers run on another model ``supply_shipx_lf (observers: supply_dp_linear)``."""
        labels: list[str] = []
        for name in self.scenario_names:
            world = self.scenarios[name] if self.scenarios is not None else self.scenario
            label = world.vessel.kind
            design = getattr(world, "design_vessel", None)
            if design is not None and design != world.vessel:
                label += f" (observers: {design.kind})"
            if label not in labels:
                labels.append(label)
        return ", ".join(labels)

    def sweep_scenario(self) -> str | None:
        """The scenario a multi-scenario experiment's sweep runs on: ``sweep.scenario``, or the swept variant's
        first (the experiment's first when it runs on all)."""
        if self.scenarios is None or self.sweep is None:
            return None
        if self.sweep.scenario is not None:
            return self.sweep.scenario
        listed = next((v.scenarios for v in self.variants if v.name == self.sweep.variant), None)
        return (listed or list(self.scenarios))[0]

    def check_windows(self, horizon: float, horizon_key: str = "scenario.horizon") -> None:
        """Every error metric's time window overlaps the run ``[0, horizon]`` (ValueError otherwise): a window
        beyond the horizon would measure nothing (and a ratio of such metrics divides by zero). The error names
        the pair ``metrics.<i>|<horizon_key>``, so that it points at the horizon when a ``--set`` just changed it."""
        for i, m in enumerate(self.metrics):
            if m.kind in ("int", "recovery"):
                continue
            start, end = m.window(horizon) if m.kind == "j_tot" else (m.t_start, m.t_end or horizon)
            if start >= min(end, horizon):
                hint = ""
                if m.kind != "j_tot" and "t_start" not in m.model_fields_set:
                    hint = f" (t_start defaults to {m.t_start:g} s: set metrics.{i}.t_start)"
                raise ValueError(f"metrics.{i}|{horizon_key}: metric '{m.label}' window [{start:g}, {end:g}] s is empty in a run of "
                                 f"{horizon:g} s{hint}")

    def _check_table(self, names: list[str], kinds: list[str]) -> None:
        """The table's metrics are the experiment's (or observer diagnostics); its ``relative`` pair and the
        paper's values name variants (or the relative row, ``<a>_vs_<b>``)."""
        for i, name in enumerate(self.table.shown):
            if name not in kinds and name not in DIAGNOSTICS:
                key = f"table.metrics.{i}" if self.table.metrics else "table.metric"
                raise ValueError(f"{key}: '{name}' is not among the metrics {kinds}")
        recorded = {s for name in self.table.shown for s in self.recorded_signals(name)}
        if unknown := [s for s in self.table.signals or [] if s not in recorded]:
            raise ValueError(f"table.signals: {unknown} are not recorded by the table's metrics (they record: "
                             f"{', '.join(sorted(recorded))})")
        rel = self.table.relative
        if rel is not None and not set(rel) <= set(names):
            raise ValueError(f"table.relative: unknown variants {sorted(set(rel) - set(names))}")
        if rel is not None and rel[0] == rel[1]:
            raise ValueError(f"table.relative: a variant against itself ({rel[0]})")
        if self.table.paper is not None:
            unknown = set(self.table.paper.values) - set(names) - ({f"{rel[0]}_vs_{rel[1]}"} if rel else set())
            if unknown:
                raise ValueError(f"table.paper.values: unknown variants {sorted(unknown)} (have: {', '.join(names)})")

    def _check_single(self, horizon_key: str = "scenario.horizon") -> Experiment:
        """A single-scenario experiment (or one scenario's part of a study, whose world's horizon is
        ``horizon_key``): unique names, metrics that apply to the world, and a table, sweep and figures that name
        its variants and metrics."""
        names = [v.name for v in self.variants]
        dup = {n for n in names if names.count(n) > 1}
        if dup:
            raise ValueError(f"variants: duplicate names {sorted(dup)}")
        kinds = self._check_metrics(horizon_key)
        if self.table is not None:
            self._check_table(names, kinds)
        if self.sweep is not None:
            self._check_sweep(names, kinds)
        files = [f.file for f in self.figures]
        if twice := sorted({f for f in files if files.count(f) > 1}):
            raise ValueError(f"figures: {twice} named twice (the second would replace the first)")
        for f in self.figures:
            if self.scenarios is None and f.scenario not in (None, self.scenario.name):
                raise ValueError(f"figures: {f.file}: scenario '{f.scenario}' is not this experiment's world "
                                 f"('{self.scenario.name}'; scenario: is for experiments with several)")
            unknown = set(f.variants or []) - set(names)
            if unknown:
                raise ValueError(f"figures: {f.file} names unknown variants {sorted(unknown)} (have: {', '.join(names)})")
        return self

    def _check_metrics(self, horizon_key: str) -> list[str]:
        """Unique metric names, closed-loop metrics on closed-loop worlds only, windows inside the run; returns the
        names."""
        kinds = [m.label for m in self.metrics]
        if len(set(kinds)) != len(kinds):
            raise ValueError(f"metrics: names must be unique, got {kinds} (give each repeated kind its own name)")
        for m in self.metrics:
            if m.kind in ("int", "recovery") and self.scenario.kind != "rov_tracking":
                named = f"'{m.label}' ({m.kind})" if m.label != m.kind else f"'{m.kind}'"
                raise ValueError(f"metrics: {named} applies to rov_tracking scenarios only")
        self.check_windows(self.scenario.horizon, horizon_key)
        return kinds

    def _check_sweep(self, names: list[str], kinds: list[str]) -> None:
        """The sweep's variant is one of the experiment's, and the metrics it shows are among its metrics."""
        if self.sweep.variant not in names:
            raise ValueError(f"sweep.variant: '{self.sweep.variant}' is not a variant (have: {', '.join(names)})")
        unknown = [v for v in self.sweep.variants or [] if v not in names]
        if unknown:
            raise ValueError(f"sweep.variants: unknown variants {unknown} (have: {', '.join(names)})")
        twice = sorted({v for v in self.sweep.variants or [] if self.sweep.variants.count(v) > 1})
        if twice:
            raise ValueError(f"sweep.variants: {twice} given more than once")
        for metric in self.sweep.shown:
            if metric not in kinds:
                key = "sweep.metrics" if self.sweep.metrics else "sweep.metric"
                raise ValueError(f"{key}: '{metric}' is not among the experiment's metrics {kinds}")
        self._check_sweep_claims(names)

    def _check_sweep_claims(self, names: list[str]) -> None:
        """Each sweep claim's metric is one the sweep shows, its signal one that metric records (before, another
        left the claim out of claims.md), and a groups claim compares two groups or two variants."""
        for i, c in enumerate(self.sweep.claims):
            if c.metric is not None and c.metric not in self.sweep.shown:
                raise ValueError(f"sweep.claims.{i}: metric '{c.metric}' is not among the sweep's metrics {self.sweep.shown}")
            metric = c.metric or self.sweep.shown[0]
            recorded = self.recorded_signals(metric)
            if c.signal is not None and c.signal not in recorded:
                raise ValueError(f"sweep.claims.{i}.signal: '{c.signal}' is not recorded by metric '{metric}' (it records: "
                                 f"{', '.join(recorded)})")
            pair = [c.above, c.below] if c.kind == "groups" else None
            if pair and not (set(pair) <= set(self.sweep.groups) or set(pair) <= set(names)):
                raise ValueError(f"sweep.claims.{i}: {pair} are neither two of the groups ({', '.join(self.sweep.groups)}) "
                                 f"nor two variants ({', '.join(names)})")
