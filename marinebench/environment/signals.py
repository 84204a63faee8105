"""Random excitation signals, one parameter draw per Monte-Carlo seed.

Bejarano et al. Sec. IV drive F_u, tau_r, F_wu, F_wv and tau_wr with "sinusoidal signals with random
amplitude, frequency and bias"; the ranges are not given and are scenario parameters here.
"""

from __future__ import annotations

from typing import Annotated, Literal

import numpy as np
from pydantic import BaseModel, Field, model_validator

from marinebench.settings import STRICT

Range = tuple[float, float]


class _RangeModel(BaseModel):
    model_config = STRICT

    @model_validator(mode="after")
    def _ordered(self):
        for name, value in self:
            if isinstance(value, tuple) and len(value) == 2 and value[0] > value[1]:
                raise ValueError(f"{name}: lower bound {value[0]} exceeds upper bound {value[1]}")
        return self


class RandomSinusoid(_RangeModel):
    """``s(t) = b + a sin(2 pi f t + phi)``, b, a, f uniform in their ranges, phi uniform in [0, 2 pi)."""

    kind: Literal["random_sinusoid"] = "random_sinusoid"
    bias: Range = Field((0.0, 0.0), description="bias range [signal unit]")
    amplitude: Range = Field((0.0, 0.0), description="amplitude range [signal unit]")
    frequency: Range = Field((0.01, 0.1), description="frequency range [Hz]")

    @model_validator(mode="after")
    def _positive(self):
        if self.amplitude[0] < 0 or self.frequency[0] < 0:
            raise ValueError("amplitude and frequency ranges must be non-negative")
        return self

    def sample(self, rngs: list[np.random.Generator]) -> SinusoidBatch:
        draws = np.array(
            [[g.uniform(*self.bias), g.uniform(*self.amplitude), g.uniform(*self.frequency), g.uniform(0, 2 * np.pi)]
             for g in rngs]
        )
        return SinusoidBatch(*draws.T)


class Constant(BaseModel):
    """A constant signal."""

    model_config = STRICT
    kind: Literal["constant"] = "constant"
    value: float = Field(0.0, description="the value, in the unit of the input it drives [N, N m]")

    def sample(self, rngs: list[np.random.Generator]) -> SinusoidBatch:
        n = len(rngs)
        return SinusoidBatch(np.full(n, self.value), np.zeros(n), np.zeros(n), np.zeros(n))


Signal = Annotated[RandomSinusoid | Constant, Field(discriminator="kind")]


class SinusoidBatch:
    """Sampled parameters of one signal for a batch of runs, each ``(B,)``."""

    def __init__(self, bias: np.ndarray, amplitude: np.ndarray, frequency: np.ndarray, phase: np.ndarray):
        self.bias, self.amplitude, self.omega, self.phase = bias, amplitude, 2 * np.pi * frequency, phase

    def __call__(self, t: float) -> np.ndarray:
        return self.bias + self.amplitude * np.sin(self.omega * t + self.phase)

    def take(self, index: np.ndarray) -> SinusoidBatch:
        return SinusoidBatch(self.bias[index], self.amplitude[index], self.omega[index] / (2 * np.pi), self.phase[index])
