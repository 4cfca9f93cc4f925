"""Measurement noise models: white Gaussian per channel plus optional quantisation.

Two named models: ``realistic`` sensors (rms x1 5 um, x3 and x4 5 kPa,
x5 0.5 um) and ``stress`` (0.1 % of each sensor's full-scale span from the rig
config); ``pct:F`` is F % of span. Everything is seeded: the same seed gives the same
noise, bit for bit.
"""

from __future__ import annotations

import numpy as np
from pydantic import BaseModel, ConfigDict, Field

from hydromon.contract import RigConfig


class NoiseModel(BaseModel):
    """Per-channel rms noise [m, Pa, Pa, m] and quantisation steps (0 = none) in the same units."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    name: str = "none"
    x1: float = Field(0.0, ge=0)
    x3: float = Field(0.0, ge=0)
    x4: float = Field(0.0, ge=0)
    x5: float = Field(0.0, ge=0)
    q_x1: float = Field(0.0, ge=0)
    q_p: float = Field(0.0, ge=0)
    q_x5: float = Field(0.0, ge=0)

    @property
    def rms(self) -> np.ndarray:
        return np.array([self.x1, self.x3, self.x4, self.x5])

    @property
    def is_zero(self) -> bool:
        return not (self.rms.any() or self.q_x1 or self.q_p or self.q_x5)


def noise_model(spec: str, config: RigConfig | None = None) -> NoiseModel:
    """``none``, ``realistic``, ``stress`` or ``pct:F`` (F % of each sensor span)."""
    config = config or RigConfig()
    if spec in ("none", "0", ""):
        return NoiseModel()
    if spec == "realistic":
        return NoiseModel(name="realistic", x1=5e-6, x3=5e3, x4=5e3, x5=0.5e-6)
    if spec == "stress":
        spec, name = "pct:0.1", "stress"
    else:
        name = spec
    if spec.startswith("pct:"):
        try:
            f = float(spec[4:]) / 100.0
        except ValueError:
            raise ValueError(f"noise {spec!r}: expected pct:NUMBER") from None
        if not (0 <= f < 1):
            raise ValueError(f"noise {spec!r}: percentage must lie in [0, 100)")
        return NoiseModel(name=name, x1=f * config.x1_span, x3=f * config.p_span,
                          x4=f * config.p_span, x5=f * config.x5_span)
    raise ValueError(f"unknown noise model {spec!r}; choose none, realistic, stress or pct:F")


def add_noise(clean: np.ndarray, model: NoiseModel, seed: int) -> np.ndarray:
    """Measured channels from clean ones.

    Parameters
    ----------
    clean : array (..., 4)
        x1 [m], x3 [Pa], x4 [Pa], x5 [m] per sample.
    seed : int
        Seed of the generator; the result is a pure function of (clean, model, seed).
    """
    out = np.array(clean, dtype=float, copy=True)
    if model.is_zero:
        return out
    rng = np.random.default_rng(seed)
    out += rng.standard_normal(out.shape) * model.rms
    for col, q in ((0, model.q_x1), (1, model.q_p), (2, model.q_p), (3, model.q_x5)):
        if q > 0:
            out[..., col] = np.round(out[..., col] / q) * q
    return out
