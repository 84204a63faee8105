"""The paper's claims as config: statements about an experiment's runs (``claims:``) or about a sweep's
curves (``sweep.claims``), checked on our results by :mod:`marinebench.results.claims` into ``claims.md``.
Paper numbers enter only ``near_paper`` claims, as the yardstick."""

from __future__ import annotations

from typing import Annotated, Literal

from pydantic import BaseModel, Field, model_validator

from marinebench.settings import STRICT


class _Claim(BaseModel):
    """A statement of the paper, checked on our runs (``claims.md``); ``metric`` and ``signals`` default to the
    table's, ``scenarios`` to every scenario its variants run on."""

    model_config = STRICT
    text: str = Field(..., min_length=1, description="the claim, in the paper's words or close to them")
    source: str = Field("", description="where the paper makes it, e.g. 'Table IV' or 'Sec. IV-B'")
    metric: str | None = Field(None, description="metric name (default: the table's metric)")
    signals: list[str] | None = Field(None, min_length=1, description="default: the table's signals")
    scenarios: list[str] | None = Field(None, min_length=1, description="multi-scenario experiments: where it is "
                                        "checked (default: every scenario all its variants run on)")

    @property
    def variant_names(self) -> list[str]:
        raise NotImplementedError

    @model_validator(mode="after")
    def _distinct_variants(self):
        """A claim compares different variants: one named twice (``a: x, b: x``) would hold or fail trivially."""
        names = self.variant_names
        if twice := sorted({n for n in names if names.count(n) > 1}):
            raise ValueError(f"names {twice} more than once: a claim compares different variants")
        return self


class LessClaim(_Claim):
    """mean(a) < factor * mean(b) for every signal and scenario (means over seeds): an ordering (factor 1),
    "cuts by 10x" (0.1), "at least 20 % below" (0.8), "at most 10 % above" (1.1). ``b`` may list several
    variants ("the best of them": below each)."""

    kind: Literal["less"] = "less"
    a: str = Field(..., description="the variant claimed lower")
    b: str | list[str] = Field(..., description="the variant (or variants: below each) it is compared with")
    factor: float = Field(1.0, gt=0, description="mean(a) < factor * mean(b): 1 an ordering, 0.8 at least 20 % below")

    @property
    def others(self) -> list[str]:
        return [self.b] if isinstance(self.b, str) else list(self.b)

    @model_validator(mode="after")
    def _some_other(self) -> LessClaim:
        if not self.others:
            raise ValueError("b: an empty list names no variant to compare with")
        return self

    @property
    def variant_names(self) -> list[str]:
        return [self.a, *self.others]


class OrderClaim(_Claim):
    """The variants' means increase in the order listed, for every signal and scenario (e.g. ``[cdo_srise,
    srise, rise]`` for "RISE > S+RISE > CDO-S+RISE")."""

    kind: Literal["order"] = "order"
    variants: list[str] = Field(..., min_length=2, description="the variants, lowest mean first")

    @property
    def variant_names(self) -> list[str]:
        return list(self.variants)


class WithinClaim(_Claim):
    """The variants' means agree for every signal and scenario: largest / smallest <= ``factor`` ("within a
    factor 1.5 of each other"), or each within ``rtol`` of the first variant's ("changes by less than 10 %")."""

    kind: Literal["within"] = "within"
    variants: list[str] = Field(..., min_length=2, description="the variants that agree")
    factor: float | None = Field(None, gt=1, description="largest / smallest mean at most this (or give rtol)")
    rtol: float | None = Field(None, gt=0, description="each mean within this fraction of the first variant's "
                               "(or give factor)")

    @model_validator(mode="after")
    def _one_bound(self) -> WithinClaim:
        if (self.factor is None) == (self.rtol is None):
            raise ValueError("give exactly one of 'factor' or 'rtol'")
        return self

    @property
    def variant_names(self) -> list[str]:
        return list(self.variants)


class AtMostClaim(_Claim):
    """Every seed's value of variant ``a`` is at most ``value`` (e.g. a recovery time within 2 s)."""

    kind: Literal["at_most"] = "at_most"
    a: str = Field(..., description="the variant")
    value: float = Field(..., description="the bound every seed's value stays at or under, in the metric's unit")

    @property
    def variant_names(self) -> list[str]:
        return [self.a]


class NearPaperClaim(_Claim):
    """Every tabulated mean of ``variants`` (default: those with paper values) is within ``factor`` of the
    paper's value (``table.paper``), either way."""

    kind: Literal["near_paper"] = "near_paper"
    factor: float = Field(2.0, gt=1, description="each mean within this factor of the paper's value, either way")
    variants: list[str] | None = Field(None, min_length=1, description="default: those with paper values")

    @property
    def variant_names(self) -> list[str]:
        return list(self.variants or [])


Claim = Annotated[LessClaim | OrderClaim | WithinClaim | AtMostClaim | NearPaperClaim, Field(discriminator="kind")]


class _SweepClaim(BaseModel):
    """A trend the paper states about a sweep, checked on the curves (mean over seeds) of each group
    (``claims.md`` of the sweep); ``metric`` defaults to the first tabulated, ``signal`` to every signal."""

    model_config = STRICT
    text: str = Field(..., min_length=1, description="the claim, in the paper's words or close to them")
    source: str = Field("", description="where the paper makes it, e.g. 'Fig. 3'")
    param: str = Field(..., description="the swept parameter (a name of sweep.params)")
    metric: str | None = Field(None, description="the metric whose curve is checked (default: the first tabulated)")
    signal: str | None = Field(None, description="the signal whose curve is checked (default: every signal)")
    groups: list[str] | None = Field(None, min_length=1, description="the groups it is checked in (default: all)")


class ProbeClaim(_SweepClaim):
    """KPI(at) < factor * KPI(vs) in every group (values interpolated as for ``probes``): "J at k = 0.7 at
    least 20 % below k = 0" is ``{param: k, at: 0.7, vs: 0, factor: 0.8}``."""

    kind: Literal["probe"] = "probe"
    at: float = Field(..., description="the parameter value claimed better")
    vs: float = Field(..., description="the parameter value it is compared with")
    factor: float = Field(1.0, gt=0, description="KPI(at) < factor * KPI(vs): 0.8 for at least 20 % below")

    @model_validator(mode="after")
    def _two_values(self) -> ProbeClaim:
        if self.at == self.vs:
            raise ValueError(f"at and vs are both {self.at:g}: a probe claim compares two values")
        return self


class TrendClaim(_SweepClaim):
    """The KPI grows with the parameter over ``range`` in every group: Spearman rank correlation of the mean
    curve above ``min_rho`` (``decreasing: true``: below ``-min_rho``)."""

    kind: Literal["trend"] = "trend"
    range: tuple[float, float] = Field(..., description="[low, high] of the parameter, ends "
                                       "included, over which the trend is checked (at least three points)")
    min_rho: float = Field(0.0, ge=0, lt=1, description="the Spearman rank correlation must exceed it "
                           "(decreasing: be below minus it)")
    decreasing: bool = Field(False, description="claim a fall instead of a rise")


class GroupsClaim(_SweepClaim):
    """Group ``above``'s mean curve lies above group ``below``'s at every value of the parameter (with ``factor``:
    ``below``'s under ``factor`` × ``above``'s, as a ``less`` claim with ``a = below``, ``b = above``). ``above`` and
    ``below`` may also name two variants, checked when both are swept side by side (``sweep --variants``), in
    each group: "CDO-S+RISE's yaw RMSE is not above S+RISE's" at every yaw-sample noise is
    ``{param: yaw_noise, above: srise, below: cdo_srise, signal: yaw}``."""

    kind: Literal["groups"] = "groups"
    above: str = Field(..., description="the group (or variant) whose curve is higher")
    below: str = Field(..., description="the group (or variant) whose curve is lower")
    factor: float = Field(1.0, gt=0, description="below's curve under factor × above's at every value (0.7: at least 30 % "
                          "under it; 1.1: at most 10 % over it)")

    @model_validator(mode="after")
    def _two_curves(self) -> GroupsClaim:
        if self.above == self.below:
            raise ValueError(f"above and below are both '{self.above}': a groups claim compares two curves")
        return self


SweepClaim = Annotated[ProbeClaim | TrendClaim | GroupsClaim, Field(discriminator="kind")]
