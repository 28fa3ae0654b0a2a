"""Measurement noise from the quiet samples before a step: its level and how correlated
it is from one sample to the next (what a likelihood and a prewhitening need)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import DataError
from .measured import MeasuredData

# Fewer pre-step samples than this give a noise level not worth reporting.
MIN_NOISE_SAMPLES = 10


@dataclass(frozen=True)
class NoiseEstimate:
    """Noise of one column, from the valid samples before ``t_end``.

    ``sigma``: standard deviation of the (detrended) samples, the white-noise level.
    ``phi``: lag-1 autocorrelation, the AR(1) coefficient *per sample interval* (so it
    depends on the recorder rate; ``dt`` is the median interval it refers to).
    ``sigma_innovation``: the AR(1) driving-noise level, ``sigma * sqrt(1 - phi**2)``.
    ``n``: samples used.
    """

    column: str
    sigma: float
    phi: float
    sigma_innovation: float
    n: int
    dt: float
    t_end: float
    detrend: bool


def noise_level(data: MeasuredData, column: str, t_end: float,
                detrend: bool = True) -> NoiseEstimate:
    """Measurement noise of ``column`` from the quiet samples before ``t_end``.

    Estimator: take the valid samples with ``time < t_end``; subtract a least-squares
    straight line in time (``detrend=True``, which removes a slow drift) or the mean.
    With residuals ``r`` and ``p`` fitted coefficients (2 or 1):

    * ``sigma = sqrt(sum r**2 / (n - p))``, the unbiased white-noise estimate;
    * ``phi = mean(r[i] * r[i-1]) / mean(r**2)``, the Yule-Walker lag-1 estimate, where
      the numerator runs over pairs of consecutive samples that are both valid (a gap
      breaks the chain rather than joining samples either side of it);
    * ``sigma_innovation = sigma * sqrt(1 - phi**2)``, from the stationary AR(1)
      variance ``sigma**2 = sigma_e**2 / (1 - phi**2)``.

    Jitter in the time stamps is ignored: consecutive samples count as one interval.
    Yule-Walker ``phi`` is biased towards zero by about ``(1 + 3 phi) / n``.
    """
    valid = data._valid(column)
    use = valid & (data.time < t_end)
    n = int(np.count_nonzero(use))
    if n < MIN_NOISE_SAMPLES:
        raise DataError(f"only {n} valid '{column}' samples before t = {t_end:g} s; the noise "
                        f"level needs at least {MIN_NOISE_SAMPLES}", data.source)
    t = data.time[use]
    y = data.columns[column][use]
    if detrend:
        A = np.column_stack([np.ones_like(t), t - t.mean()])
        coef, *_ = np.linalg.lstsq(A, y, rcond=None)
        r_used = y - A @ coef
        p = 2
    else:
        r_used = y - y.mean()
        p = 1
    ss = float(np.sum(r_used ** 2))
    sigma = float(np.sqrt(ss / (n - p)))
    # Residuals back on the full index so that consecutive pairs are found across gaps.
    r = np.zeros(data.time.shape)
    r[use] = r_used
    pair = use[1:] & use[:-1]
    n_pairs = int(np.count_nonzero(pair))
    if n_pairs == 0 or ss == 0.0:
        phi = 0.0
    else:
        phi = float((np.sum(r[1:][pair] * r[:-1][pair]) / n_pairs) / (ss / n))
    phi = float(np.clip(phi, -1.0, 1.0))
    dt = float(np.median(np.diff(t))) if n > 1 else float("nan")
    return NoiseEstimate(column, sigma, phi, sigma * float(np.sqrt(1.0 - phi ** 2)),
                         n, dt, float(t_end), detrend)


def ar1_inflation(phi: float) -> float:
    """Variance factor ``(1 + phi) / (1 - phi)`` of a mean of AR(1) noise of lag-1
    correlation ``phi`` (negative phi taken as 0, phi capped at 0.99)."""
    phi = min(max(float(phi), 0.0), 0.99)
    return (1 + phi) / (1 - phi)
