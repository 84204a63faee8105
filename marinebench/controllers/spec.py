"""The controller of a closed-loop variant: RISE, S+RISE or a class of your own, with its feedback source and
output unit.

A custom controller (``kind: custom, source: file.py:Class, params: {...}``; ``marinebench/plugins.py`` loads it)
is built as ``Class(params, batch)`` and implements ``command(e1, e1_dot, h) -> tau``: the tracking errors
``e1 = eta_d - eta`` and their rates, ``(batch, 2)`` for (depth [m], yaw [rad]), and the control period ``h`` [s];
``tau (batch, 2)`` in N and N m (before ``output_scale``; thrust allocation and saturation follow). It keeps its
own state (integrals) between calls, one row per run. Its commands are checked to be ``(batch, 2)`` at validation
and at every control step (:class:`CheckedController`)."""

from __future__ import annotations

from typing import Any, ClassVar, Literal

import numpy as np
from pydantic import BaseModel, Field, model_validator

from marinebench.controllers.rise import RISE_PRESETS, TABLE_II_DEPTH, TABLE_II_YAW, Rise, RiseGains, SRise, SRiseGains
from marinebench.errors import ProtocolError
from marinebench.plugins import user_class
from marinebench.settings import STRICT, over

# The unit of tau is not stated in the paper. RISE: SubjuGator gains in N / N m. S+RISE (Table II): yaw read
# as kgf (x9.81); depth calibrated to x40 (a literal reading is unstable on the Leonard-like heave, README).
DEFAULT_SCALE = {"rise": (1.0, 1.0), "srise": (40.0, 9.81), "custom": (1.0, 1.0)}
CUSTOM_MEMBERS = ("command",)  # what a custom controller class must have (the module docstring)


class ControllerSpec(BaseModel):
    """The controller of a variant in a closed-loop (rov_tracking) scenario."""

    model_config = STRICT
    #: settings read by some kinds only: another kind's are refused (off their defaults), and ``marinebench list
    #: KIND`` lists a kind's own
    ONLY_FOR: ClassVar[dict[str, tuple[str, ...]]] = {
        "preset": ("rise",), "depth": ("rise", "srise"), "yaw": ("rise", "srise"), "source": ("custom",), "params": ("custom",)}
    kind: Literal["rise", "srise", "custom"]
    feedback: Literal["measured", "cdo", "eo", "custom"] = Field(
        "measured", description="measured: the held samples and rates (sensors.depth_rate / yaw_rate); cdo/eo: the "
        "observer's estimates of eta and eta_dot; custom: those of the variant's own observer (observer: {kind: custom})"
    )
    output_scale: float | tuple[float, float] | Literal["inertia"] | None = Field(
        None, description="multiplies the command (depth, yaw) before allocation: 1 reads the gains as producing N "
        "and N m, 9.81 as kgf, 'inertia' as accelerations (tau = M_hat nu, the nominal inertia with added mass); "
        "the paper does not state the unit of tau. Default: RISE (1, 1); S+RISE (40, 9.81), see DEFAULT_SCALE",
    )

    disturbance_feedforward: bool | tuple[bool, bool] = Field(
        False, description="cdo/eo/custom feedback only: subtract M_hat times the observer's lumped-disturbance "
        "estimate (x_hat_3; a custom observer's depth_disturbance, yaw_disturbance) from the command, so the "
        "controller is fed the observer's state and disturbance estimates (Tijjani Sec. IV); one flag, or (depth, yaw)",
    )
    preset: Literal["subjugator", "table2_equivalent"] = Field(
        "subjugator", description="RISE gains (Tijjani does not publish its own): SubjuGator's z/yaw entries, or "
        "Table II's S+RISE gains at their small-error constants (baselines.md 5.2)",
    )
    depth: dict[str, float] = Field(default_factory=dict, description="gain overrides for depth")
    yaw: dict[str, float] = Field(default_factory=dict, description="gain overrides for yaw")
    source: str | None = Field(None, description="custom: file.py:ClassName (relative to the experiment file) or "
                               "package.module:ClassName (see the module docstring)")
    params: dict[str, Any] = Field(default_factory=dict, description="custom: passed to the class")

    @model_validator(mode="after")
    def _feedforward_needs_an_observer(self):
        if self.output_scale not in (None, "inertia") and (np.asarray(self.output_scale, dtype=float) <= 0).any():
            raise ValueError("output_scale must be positive")
        if any(self.feedforward_mask()) and self.feedback == "measured":
            raise ValueError("disturbance_feedforward needs feedback 'cdo', 'eo' or 'custom' (an observer's estimate)")
        if self.kind == "custom" and self.source is None:
            raise ValueError("source: a custom controller needs source: file.py:ClassName")
        if foreign := [f for f, kinds in self.ONLY_FOR.items() if self.kind not in kinds
                       and getattr(self, f) != type(self).model_fields[f].get_default(call_default_factory=True)]:
            if self.kind == "custom":
                raise ValueError("a custom controller takes its settings in 'params' (not preset, depth, yaw)")
            if "preset" in foreign:  # before: ignored by S+RISE
                raise ValueError("preset chooses RISE's gains; S+RISE's are Table II's (override them with depth, yaw)")
            raise ValueError(f"source and params are for custom controllers, not {self.kind}")
        if self.kind == "custom":
            user_class(self.source, CUSTOM_MEMBERS)
        else:
            self.gains()  # unknown or out-of-range gain overrides are config errors, not ignored
        return self

    def gains(self) -> list[RiseGains] | list[SRiseGains]:
        """(depth, yaw) gains: Table II (S+RISE) or the RISE preset, with ``depth``/``yaw`` overrides applied."""
        model, base = (SRiseGains, (TABLE_II_DEPTH, TABLE_II_YAW)) if self.kind == "srise" else (RiseGains, RISE_PRESETS[self.preset])
        return [over(model, default.model_dump(), settings, dof, f"{self.kind} gain")
                for dof, default, settings in zip(("depth", "yaw"), base, (self.depth, self.yaw))]

    def feedforward_mask(self) -> np.ndarray:
        """Per DOF (depth, yaw): whether the disturbance estimate is fed forward."""
        return np.broadcast_to(np.asarray(self.disturbance_feedforward, dtype=bool), (2,)).copy()

    def scale(self, inertia: np.ndarray) -> np.ndarray:
        """The (depth, yaw) output multipliers."""
        if self.output_scale == "inertia":
            return np.asarray(inertia, dtype=float)
        scale = DEFAULT_SCALE[self.kind] if self.output_scale is None else self.output_scale
        return np.broadcast_to(np.asarray(scale, dtype=float), (2,)).copy()

    def build(self, batch: int):
        if self.kind == "custom":
            return CheckedController(user_class(self.source, CUSTOM_MEMBERS)(self.params, batch), batch)
        return (SRise if self.kind == "srise" else Rise)(self.gains(), batch)


def check_built(controller: Any, h: float) -> None:
    """A custom controller built for one run, asked once for its command at zero error (a ProtocolError unless it is
    a finite (1, 2) array): a mistake in the class is then a config error before anything runs."""
    zero = np.zeros((1, 2))
    checked = controller if isinstance(controller, CheckedController) else CheckedController(controller, 1)
    tau = checked.command(zero, zero.copy(), h)
    if not np.all(np.isfinite(tau)):
        raise ProtocolError(f"{checked.name}.command() at zero error returned {tau.tolist()!r}: expected finite values")


class CheckedController:
    """A built custom controller whose every command is checked to be ``(batch, 2)`` numbers (depth, yaw), at
    validation (:func:`check_built`) and at every control step of the runs: one column, one row or a scalar would
    otherwise be broadcast to every run and DOF (wrong numbers, no error). A wrong answer is a :class:`ProtocolError`;
    non-finite values are allowed while running (a diverged run, reported as such)."""

    def __init__(self, inner: Any, batch: int) -> None:
        self.inner, self.batch, self.name = inner, batch, type(inner).__name__

    def command(self, e1: np.ndarray, e1_dot: np.ndarray, h: float) -> np.ndarray:
        value = self.inner.command(e1, e1_dot, h)
        try:
            tau = np.asarray(value, dtype=float) if value is not None else None
        except (TypeError, ValueError):
            tau = None
        if tau is None or tau.shape != (self.batch, 2):
            raise ProtocolError(f"{self.name}.command() returned {type(value).__name__} of shape {np.shape(value)}: "
                                f"expected numbers (B, 2) = ({self.batch}, 2), depth and yaw")
        return tau
