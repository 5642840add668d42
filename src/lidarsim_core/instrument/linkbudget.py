r"""The link budget: received signal, detection probability and intensity of a return.

Signal
------
For a target filling the beam, the received power of a pulse is proportional to the
target's apparent reflectivity over a power of the range (the LiDAR equation; n = 2 for an
extended target in vacuum):

.. math::  S = C\, \rho_\mathrm{eff} / R^n

``S`` is expressed in units of the detection threshold. The sensor constant ``C`` (and ``n``
when the datasheet gives two or more figures) is calibrated from the datasheet's
range-at-reflectivity figures, read as the ranges of 50 % detection probability of a
Lambertian target at normal incidence: ``S(ρ_i, R_i) = 1``, i.e. ``ln R = (ln C + ln ρ)/n``,
fitted by least squares in ``ln R``. A fitted n a little below 2 absorbs the vendor's test
conditions (air, daylight background).

With divergence on, a return gathers the sub-rays of one pulse hit at about the same range,
each carrying its share ``w_k`` of the pulse energy: ``S = C Σ w_k ρ_eff,k / R_k^n``.

Detection
---------
A linear-mode receiver compares the echo amplitude, plus Gaussian noise σ_n, with a
threshold T. With S in threshold units and ``TNR = T/σ_n`` (threshold-to-noise ratio):

.. math::  P_d = \Phi\big(\mathrm{TNR}\,(S - 1)\big)

so P_d = 50 % exactly where the datasheet says, and the curve is steeper for a larger TNR.

Intensity
---------
The intensity written per point is the *apparent reflectivity* ``S R^n / C``: the
reflectivity of a beam-filling Lambertian target at normal incidence that would give the
same signal at that range (what Livox, Velodyne and Ouster report as calibrated
"reflectivity"): 0.2 for a 20 % target seen face-on, 0.1 at 60° incidence, about half its
reflectivity for a beam half on an edge, above 1 for glints and retro-reflectors.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..base.errors import ConfigError
from ..scenario.datasheet import RangeAtReflectivity, SensorDatasheet
from ..scenario.sensor import DetectionConfig


@dataclass(frozen=True)
class LinkBudget:
    """``S = C ρ_eff / R^n`` in units of the detection threshold.

    Attributes
    ----------
    constant
        C (m^n).
    exponent
        n.
    threshold_to_noise
        TNR of :func:`detection_probability`.
    """

    constant: float
    exponent: float
    threshold_to_noise: float = 4.0

    @classmethod
    def fit(cls, figures: list[RangeAtReflectivity], *, exponent: float | None = None,
            threshold_to_noise: float = 4.0) -> "LinkBudget":
        """Calibrate C (and n, from two or more figures) on range-at-reflectivity figures."""
        rho = np.log([f.reflectivity for f in figures])
        rng = np.log([f.range_m for f in figures])
        if exponent is None:
            if len(figures) >= 2 and np.ptp(rho) > 0:
                slope, _ = np.polyfit(rho, rng, 1)  # ln R = ln C / n + ln ρ / n
                exponent = 1.0 / slope
            else:
                exponent = 2.0
        # least squares in ln R for the given n: ln C = mean(n ln R - ln ρ)
        log_c = float(np.mean(exponent * rng - rho))
        return cls(math.exp(log_c), float(exponent), threshold_to_noise)

    def signal(self, rho_eff: np.ndarray, range_m: np.ndarray) -> np.ndarray:
        """S for apparent reflectivities at ranges (threshold units)."""
        return self.constant * np.asarray(rho_eff) / np.asarray(range_m) ** self.exponent

    def apparent_reflectivity(self, signal: np.ndarray, range_m: np.ndarray) -> np.ndarray:
        """The intensity: ``S R^n / C``."""
        return np.asarray(signal) * np.asarray(range_m) ** self.exponent / self.constant

    def detection_probability(self, signal: np.ndarray) -> np.ndarray:
        """P_d = Φ(TNR (S - 1))."""
        from scipy.special import ndtr

        return ndtr(self.threshold_to_noise * (np.asarray(signal, dtype=np.float64) - 1.0))

    def range_at(self, reflectivity: float, probability: float = 0.5) -> float:
        """Range (m) at which a beam-filling Lambertian target of ``reflectivity`` at normal
        incidence is detected with ``probability``."""
        from scipy.special import ndtri

        signal = 1.0 + float(ndtri(probability)) / self.threshold_to_noise
        if signal <= 0:
            return math.inf
        return (self.constant * reflectivity / signal) ** (1.0 / self.exponent)


def link_budget(config: DetectionConfig, sheet: SensorDatasheet, *, source: str) -> LinkBudget:
    """The calibrated link budget of a sensor.

    Raises
    ------
    ConfigError
        When neither the detection block nor the datasheet gives range-at-reflectivity
        figures.
    """
    figures = config.range_at_reflectivity or sheet.range_at_reflectivity
    if not figures:
        raise ConfigError(f"the detection model needs range-at-reflectivity figures and "
                          f"datasheet '{sheet.name}' gives none; add them here",
                          source=source, field="sensor.detection.range_at_reflectivity")
    return LinkBudget.fit(list(figures), exponent=config.range_exponent,
                          threshold_to_noise=config.threshold_to_noise)


def detection_range_limit(config: DetectionConfig, sheet: SensorDatasheet) -> float:
    """The hard range limit with the detection model on (m)."""
    if config.range_max_m is not None:
        return config.range_max_m
    figures = config.range_at_reflectivity or sheet.range_at_reflectivity
    return max([sheet.range_max_m, *(f.range_m for f in figures)])
