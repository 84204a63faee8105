"""Bounded, band-limited position noise (Bejarano et al. Sec. IV, Assumption 3).

The paper says "uniformly distributed random noises ... within +-0.2 m and frequency range between 0.1
and 0.5 Hz" without the generator. Here the noise is a multisine: ``n_components`` sinusoids with
frequencies uniform in ``[f_low, f_high]`` and uniform phases, scaled to the standard deviation of a
uniform variable on ``[-bound, bound]`` (``bound/sqrt(3)``) and saturated at ``+-bound``. It is
strictly band-limited before saturation, bounded as Assumption 3 requires, a continuous function of
time (so RK4 stages see a consistent signal), and reproducible per seed.
"""

from __future__ import annotations

from typing import Annotated, Literal

import numpy as np
from pydantic import BaseModel, Field, model_validator

from marinebench.settings import STRICT


class NoNoise(BaseModel):
    """Noiseless measurement."""

    model_config = STRICT
    kind: Literal["none"] = "none"

    def sample(self, rngs: list[np.random.Generator], channels: int) -> NoiseBatch | None:
        return None


class BandLimitedUniform(BaseModel):
    """Bounded, band-limited noise (Bejarano Assumption 3): a multisine in [f_low, f_high] saturated at ±bound."""

    model_config = STRICT
    kind: Literal["bandlimited_uniform"] = "bandlimited_uniform"
    bound: float = Field(0.2, gt=0, description="saturation bound n_p* [m]")
    f_low: float = Field(0.1, gt=0, description="lowest frequency [Hz]")
    f_high: float = Field(0.5, gt=0, description="highest frequency [Hz]")
    n_components: int = Field(40, ge=1, le=1000, description="number of sinusoids")
    spacing: Literal["uniform", "log"] = Field(
        "uniform", description="frequency distribution of the components: uniform in Hz or log-uniform"
    )
    rms: float | None = Field(None, gt=0, description="standard deviation before saturation; default bound/sqrt(3)")

    @model_validator(mode="after")
    def _band(self):
        if self.f_low >= self.f_high:
            raise ValueError(f"f_low={self.f_low} must be below f_high={self.f_high}")
        return self

    def _support(self) -> tuple[float, float]:
        """Where the component frequencies are drawn uniformly: [f_low, f_high] in Hz, or in log Hz."""
        return (np.log(self.f_low), np.log(self.f_high)) if self.spacing == "log" else (self.f_low, self.f_high)

    def _hz(self, drawn: np.ndarray) -> np.ndarray:
        """Frequencies [Hz] from points of :meth:`_support`."""
        return np.exp(drawn) if self.spacing == "log" else drawn

    @property
    def std(self) -> float:
        """Standard deviation before saturation: ``rms``, or that of U(-bound, bound)."""
        return self.rms if self.rms is not None else self.bound / np.sqrt(3.0)

    def response_std(self, response, points: int = 4001) -> np.ndarray:
        """Expected std of a linear system's steady-state response to this noise (before saturation):
        ``rms * sqrt(E|H(2 pi f)|^2)`` over the components' frequency distribution. ``response(omega)`` gives
        ``H`` at angular frequencies [rad/s] along its last axis; leading axes (several outputs) are kept."""
        freq = self._hz(np.linspace(*self._support(), points))
        power = np.abs(response(2 * np.pi * freq)) ** 2
        mean = np.sum((power[..., 1:] + power[..., :-1]) / 2, axis=-1) / (points - 1)  # trapezoid mean over the distribution
        return self.std * np.sqrt(mean)

    def sample(self, rngs: list[np.random.Generator], channels: int) -> NoiseBatch:
        K = self.n_components
        lo, hi = self._support()
        freq = self._hz(np.array([g.uniform(lo, hi, (channels, K)) for g in rngs]))
        phase = np.array([g.uniform(0, 2 * np.pi, (channels, K)) for g in rngs])
        return NoiseBatch(2 * np.pi * freq, phase, self.std * np.sqrt(2.0 / K), self.bound)


Noise = Annotated[NoNoise | BandLimitedUniform, Field(discriminator="kind")]


class NoiseBatch:
    """Noise of a batch of runs: ``omega, phase (B, channels, K)``."""

    def __init__(self, omega: np.ndarray, phase: np.ndarray, amplitude: float, bound: float) -> None:
        self.omega, self.phase, self.amplitude, self.bound = omega, phase, amplitude, bound

    def __call__(self, t: float) -> np.ndarray:
        n = self.amplitude * np.sin(self.omega * t + self.phase).sum(axis=-1)
        return np.clip(n, -self.bound, self.bound)

    def take(self, index: np.ndarray) -> NoiseBatch:
        return NoiseBatch(self.omega[index], self.phase[index], self.amplitude, self.bound)
