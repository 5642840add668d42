r"""Receiver dynamic range: saturation and range walk (docs/realism.md, "Receiver dynamic
range").

**Saturation.** The receiver's output clips at a signal ``S_sat`` (threshold units of the
calibrated link budget): a detected return's signal becomes ``min(S, S_sat)`` and its
intensity (apparent reflectivity, ``S R^n / C``) is clipped accordingly, at
``S_sat R^n / C``: close retro-reflectors and glints all read the same.

**Range walk.** A leading-edge discriminator fires when the echo crosses the threshold. For a
Gaussian pulse of RMS length σ_R (in range units), an echo of peak S (threshold units) crosses
``σ_R √(2 ln S)`` before its peak. Sensors correct this walk from the measured amplitude; once
the amplitude saturates they can no longer, and a return of true signal S > S_sat is reported
early by

.. math::  ΔR(S) = −σ_R \left(\sqrt{2 \ln S} − \sqrt{2 \ln S_\mathrm{sat}}\right),
           \quad S > S_\mathrm{sat}\ (0 \text{ below})

σ_R defaults to ``range_resolution_m / 2.3548`` (the resolution ≈ c τ/2 read as the pulse's
FWHM in range units).

Reads and writes ``piece.cand`` (signal, intensity, range of detected candidates; re-sorted by
(pulse, range) when the walk reorders a pulse's returns).
"""

from __future__ import annotations

import math

import numpy as np

from ...base.errors import ConfigError
from ...instrument.returns import Candidates
from ...scenario.sensor import ReceiverConfig
from ..context import RunContext
from .base import Piece

#: FWHM of a Gaussian over its σ: 2 √(2 ln 2).
FWHM_PER_SIGMA = 2.0 * math.sqrt(2.0 * math.log(2.0))


def range_walk(signal: np.ndarray, saturation: float, sigma_m: float) -> np.ndarray:
    """ΔR(S) = −σ_R (√(2 ln S) − √(2 ln S_sat)) for S > S_sat, else 0 (m)."""
    s = np.maximum(np.asarray(signal, dtype=np.float64), saturation)
    return -sigma_m * (np.sqrt(2.0 * np.log(s)) - math.sqrt(2.0 * math.log(saturation)))


class ReceiverStage:
    """Saturation and range walk of detected returns (see the module docstring)."""

    name = "receiver"

    def __init__(self, ctx: RunContext, config: ReceiverConfig) -> None:
        src = ctx.scenario.source
        if ctx.link is None:
            raise ConfigError("the receiver's saturation is a signal level of the link "
                              "budget; add 'detection: {}' to the sensor", source=src,
                              field="sensor.receiver")
        self.link = ctx.link
        saturation = config.saturation_signal or ctx.sensor.saturation_signal
        if saturation is None:
            raise ConfigError(f"datasheet '{ctx.sensor.name}' gives no saturation_signal; "
                              "give it here", source=src,
                              field="sensor.receiver.saturation_signal")
        self.saturation = saturation
        self.sigma_m: float | None = None
        if config.range_walk:
            sigma = config.pulse_sigma_m
            if sigma is None:
                if ctx.range_resolution_m is None:
                    raise ConfigError(f"datasheet '{ctx.sensor.name}' gives no "
                                      "range_resolution_m to derive the pulse length from; "
                                      "give pulse_sigma_m", source=src,
                                      field="sensor.receiver.pulse_sigma_m")
                sigma = ctx.range_resolution_m / FWHM_PER_SIGMA
            self.sigma_m = sigma

    def info(self) -> dict:
        """Frame metadata: the saturation level and the walk's pulse length (None: no walk)."""
        return {"saturation_signal": self.saturation, "range_walk_sigma_m": self.sigma_m}

    def run(self, piece: Piece) -> None:
        cand = piece.cand
        hot = np.flatnonzero(piece.detected & (cand.signal > self.saturation))
        if not len(hot):
            return
        signal, intensity, rng = cand.signal.copy(), cand.intensity.copy(), cand.range.copy()
        if self.sigma_m is not None:
            rng[hot] += range_walk(signal[hot], self.saturation, self.sigma_m)
        signal[hot] = self.saturation
        intensity[hot] = self.link.apparent_reflectivity(signal[hot], rng[hot])
        cand = Candidates(**{**cand.__dict__, "signal": signal, "intensity": intensity,
                             "range": rng})
        order = np.lexsort((cand.range, cand.pulse))
        if np.any(order != np.arange(len(order))):  # the walk moved a return past another
            piece.detected = piece.detected[order]
            cand = Candidates(**{k: None if v is None else v[order]
                                 for k, v in cand.__dict__.items()})
        piece.cand = cand
