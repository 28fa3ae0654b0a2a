"""Problem + trajectories -> RSSD / ARSSD / likelihood.

The fitness follows Algorithm 1 (line 14) of the paper: for one output,

    RSSD = (1/M) * sum_i (y_i - yhat_i)**2

over the M valid measured samples inside the fitness window, with the simulation
``yhat`` sampled onto the measured time base. It is a mean squared difference in the
output's units (pu**2), not normalised by the signal, which is what the paper's
fitness values (about 1e-4 for pm near 0.6 pu) are. With several outputs an experiment's
RSSD is the weighted mean of the outputs' RSSDs; ARSSD is the plain mean over
experiments.

Measurement offset: with ``offset=True`` a constant offset ``c`` per output
(``y = yhat + c + noise``; a positive ``c`` means the transducer reads high) is
profiled out in closed form, ``c = mean(y - yhat)``, and the RSSD is that of
``y - yhat - c``.

Whitened fitness: an experiment whose config gives the recorder's noise model
(``[noise]``, :mod:`rapid_cosim.noise`) is scored by generalised least squares instead.
Its residual is whitened by that model (standardised Kalman innovations on the samples as
stamped: :mod:`rapid_cosim.noise.whitening`), the offset is the GLS one (the
whitened residual projected off the whitened constant), and the experiment's value is
the mean squared whitened residual: 1 for a model that leaves only the noise described.
A problem of such experiments weights them by their sample counts
(:func:`combination_weights`), so the fitness is the Gaussian deviance per sample. The
paper's RSSD path is untouched, so archived runs re-run bit for bit.

This module receives arrays only; it knows nothing of simulators or FMUs. A simulated
value that is not finite where it is scored is a :class:`SimulationError`, as is a
simulation that does not cover the measured samples (it stopped early): the evaluator
counts both as failed runs.
"""

from __future__ import annotations

import weakref
from dataclasses import dataclass, field

import numpy as np

from rapid_cosim.data import sample_onto
from rapid_cosim.errors import ConfigError, SimulationError
from rapid_cosim.experiment import Experiment, config_key
from rapid_cosim.noise.whitening import Whitening, whitening


@dataclass(frozen=True, eq=False)
class Fit:
    """Residuals of one set of outputs (columns of ``residual``).

    ``rssd`` is the weighted mean of ``per_output``; ``offset`` holds the profiled
    offsets (zeros when not profiled); ``residual`` is ``y - yhat - offset`` shaped like
    the input, NaN where a sample is not valid.
    """

    rssd: float
    per_output: np.ndarray
    offset: np.ndarray
    residual: np.ndarray
    n_valid: np.ndarray


def fit_outputs(measured, simulated, valid, weights=None, offset: bool = False) -> Fit:
    """RSSD with its parts. Arrays are (M,) for one output or (M, K) for K outputs;
    ``valid`` marks the samples that count (mask and window already applied);
    ``weights`` has one entry per output (default equal). Outputs of weight zero may
    have no valid samples; any other output needs at least one."""
    y = np.asarray(measured, dtype=np.float64)
    yhat = np.asarray(simulated, dtype=np.float64)
    ok = np.asarray(valid, dtype=bool)
    if y.ndim not in (1, 2) or yhat.shape != y.shape or ok.shape != y.shape:
        raise ValueError(f"measured {y.shape}, simulated {yhat.shape} and valid {ok.shape} "
                         f"must have the same (M,) or (M, K) shape")
    one = y.ndim == 1
    if one:
        y, yhat, ok = y[:, None], yhat[:, None], ok[:, None]
    w = _weights(weights, y.shape[1])
    if np.any(ok & ~np.isfinite(y)):
        raise ValueError("measured values marked valid must be finite")
    if np.any(ok & ~np.isfinite(yhat)):
        raise SimulationError("the simulated output is not finite at scored samples")
    total, per_output, c, residual = _batch_fit(y, yhat[None], ok, w, offset, residuals=True)
    return Fit(float(total[0]), per_output[0], c[0], residual[0][:, 0] if one else residual[0], ok.sum(axis=0))


def _weights(weights, k: int) -> np.ndarray:
    w = np.ones(k) if weights is None else np.asarray(weights, dtype=np.float64).reshape(-1)
    if w.shape != (k,) or np.any(~np.isfinite(w)) or np.any(w < 0) or not np.any(w > 0):
        raise ValueError(f"weights must be {k} finite non-negative numbers, not all zero; got {w}")
    return w


def _batch_fit(y, yhat, ok, w, offset: bool, residuals: bool = False):
    """The RSSD of each of n simulations ``yhat`` (n, M, K) against ``y`` (M, K).

    Each output's valid samples are gathered into one contiguous (n, M_k) block, so that
    every row is summed exactly as a single simulation's samples would be (numpy's
    pairwise sum along the last axis): a batch scores each set bit for bit as one call
    per set did, and archived runs re-run identically.
    """
    n, _, k = yhat.shape
    n_valid = ok.sum(axis=0)
    per_output = np.full((n, k), np.nan)
    c = np.zeros((n, k))
    residual = np.full(yhat.shape, np.nan) if residuals else None
    for j in range(k):
        if n_valid[j] == 0:
            if w[j] > 0:
                raise ValueError(f"output {j} has weight {w[j]:g} but no valid samples")
            continue
        r = np.ascontiguousarray(y[ok[:, j], j] - yhat[:, ok[:, j], j])  # rows contiguous, see above
        if offset:
            c[:, j] = r.mean(axis=1)
            r = r - c[:, j, None]
        per_output[:, j] = np.mean(r ** 2, axis=1)
        if residuals:
            residual[:, ok[:, j], j] = r
    used = w > 0
    total = np.sum(w[used] * per_output[:, used], axis=1) / np.sum(w[used])
    return total, per_output, c, residual


_WHITENINGS: "weakref.WeakKeyDictionary" = weakref.WeakKeyDictionary()


def whitenings(exp: Experiment) -> dict[int, Whitening]:
    """Per output column of positive weight: its :class:`Whitening` (made once per
    experiment, as every batch needs them)."""
    cached = _WHITENINGS.get(exp)
    if cached is None:
        t = exp.windowed_data().time
        first = int(np.searchsorted(exp.data.time, t[0]))  # the window is a slice of the record
        cached = {j: whitening(exp.noise_models[exp.scored.outputs[j]], t[index], first + index)
                  for j, index, _ in exp.scored.columns}
        _WHITENINGS[exp] = cached
    return cached


def is_whitened(exp: Experiment) -> bool:
    return bool(getattr(exp, "noise_models", None))


def combination_weights(experiments) -> np.ndarray | None:
    """How a problem's fitness weighs its experiments: equally (None: the paper's ARSSD),
    or, for whitened experiments, by their scored samples (the deviance per sample).
    Mixing the two in one problem is refused."""
    kinds = {is_whitened(e) for e in experiments}
    if len(kinds) > 1:
        first = next(e for e in experiments if is_whitened(e))
        other = next(e for e in experiments if not is_whitened(e))
        raise ConfigError(f"{first.name} gives a [noise] model (whitened fitness) but {other.name} does not; a "
                          "joint fit scores every experiment the same way", str(other.config_path), "noise")
    if not kinds.pop():
        return None
    return np.array([sum(index.size for _, index, _ in e.scored.columns) for e in experiments], dtype=float)


def batch_scores(exp: Experiment, simulated: np.ndarray, residuals: bool = False):
    """(values, residual rows or None) of a batch: the values are :func:`batch_rssd`'s,
    the residual rows (``residuals=True``) have squares summing to them: whitened with the
    GLS offset projected out for a whitened experiment, the plain offset-removed residual
    otherwise, outputs concatenated, each scaled by its weight and sample count;
    non-finite where a set's simulation is not finite. A whitened experiment is whitened
    once for both, so a least-squares method's values are bit for bit any other method's."""
    yhat = np.asarray(simulated, dtype=np.float64)
    if not residuals:
        return batch_rssd(exp, yhat), None
    scored = exp.scored
    total_w = np.sum(scored.weights[scored.weights > 0])
    if is_whitened(exp):
        with np.errstate(invalid="ignore", over="ignore"):
            values, blocks = _batch_whitened(exp, yhat, keep=True)
    else:
        values, blocks = batch_rssd(exp, yhat), []
        for j, index, y in scored.columns:
            r = y - np.take(yhat[:, :, j], index, axis=1)
            blocks.append(r - r.mean(axis=1)[:, None] if exp.offset else r)
    parts = [b * np.sqrt(scored.weights[j] / (total_w * index.size))
             for b, (j, index, _) in zip(blocks, scored.columns)]
    return values, np.concatenate(parts, axis=1)


def batch_residuals(exp: Experiment, simulated: np.ndarray) -> np.ndarray:
    """The residual rows of :func:`batch_scores`."""
    return batch_scores(exp, simulated, residuals=True)[1]


def _batch_whitened(exp: Experiment, yhat: np.ndarray, keep: bool = False):
    """Values of a whitened experiment's batch (and, with ``keep``, its whitened residual
    blocks, one per output)."""
    scored = exp.scored
    w = whitenings(exp)
    total = np.zeros(yhat.shape[0])
    blocks = []
    for j, index, y in scored.columns:
        e = w[j].residual(y - np.take(yhat[:, :, j], index, axis=1), exp.offset)
        total += scored.weights[j] * np.mean(e * e, axis=1)
        if keep:
            blocks.append(e)
    total /= np.sum(scored.weights[scored.weights > 0])
    total[~np.isfinite(total)] = np.inf
    return (total, blocks) if keep else total


def batch_rssd(exp: Experiment, simulated: np.ndarray) -> np.ndarray:
    """RSSD of each simulation of ``exp`` in a batch: ``simulated`` is (sets, samples,
    outputs) at the measured samples inside the window, outputs in ``exp.outputs``
    order. A set with a non-finite value where it is scored gets ``inf``.

    The same arithmetic as :func:`fit_outputs` (rows gathered contiguously, outputs
    accumulated in order), so each set scores bit for bit as it would alone; written
    out here because the estimators call it thousands of times with small batches.
    """
    scored = exp.scored
    yhat = np.asarray(simulated, dtype=np.float64)
    if yhat.ndim != 3 or yhat.shape[1:] != scored.measured.shape:
        raise ValueError(f"{exp.name}: simulated {yhat.shape}, expected (sets, {scored.measured.shape[0]}, "
                         f"{scored.measured.shape[1]})")
    if is_whitened(exp):
        with np.errstate(invalid="ignore", over="ignore"):
            return _batch_whitened(exp, yhat)
    total = np.zeros(yhat.shape[0])
    for j, index, y in scored.columns:
        r = y - np.take(yhat[:, :, j], index, axis=1)
        if exp.offset:
            r -= r.mean(axis=1)[:, None]
        total += scored.weights[j] * np.mean(r * r, axis=1)
    total /= np.sum(scored.weights[scored.weights > 0])
    total[~np.isfinite(total)] = np.inf
    return total


def rssd(measured, simulated, valid, weights=None, offset: bool = False) -> float:
    """Algorithm 1, line 14: mean squared difference over valid samples (weighted mean
    over outputs; measurement offset profiled out with ``offset``). :func:`fit_outputs`
    returns the offsets and residuals as well."""
    return fit_outputs(measured, simulated, valid, weights, offset).rssd


def arssd(values, weights: np.ndarray | None = None):
    """The paper's ARSSD: mean of the experiments' RSSDs along the last axis (weighted by
    ``weights`` when given: :func:`combination_weights`).

    A float for a 1-D input (one value per experiment); an (n,) array for an (n, E)
    batch. An infinite (failed) RSSD makes the average infinite.
    """
    v = np.asarray(values, dtype=np.float64)
    if v.ndim == 0 or v.shape[-1] == 0:
        raise ValueError("arssd needs at least one experiment's RSSD")
    # einsum, not BLAS: a set's value must not depend on the rows scored beside it
    # (noise.runs.rowwise says why)
    mean = v.mean(axis=-1) if weights is None else \
        np.einsum("...j,j->...", np.ascontiguousarray(v), np.asarray(weights, dtype=np.float64)) / np.sum(weights)
    return float(mean) if v.ndim == 1 else mean


@dataclass(frozen=True, eq=False)
class ExperimentFit:
    """How one simulation matches one experiment, on the measured time base.

    ``time`` holds the measured times inside the fitness window; ``residuals`` are
    ``y - yhat - offset`` on it (NaN where masked); ``n_samples`` is the number of
    valid samples scored, summed over outputs of positive weight (the ``M`` of the
    likelihood). For a whitened experiment ``rssd`` is the mean squared whitened
    residual, the offsets are the GLS ones, and ``whitened`` holds the whitened residuals
    (empty otherwise).
    """

    experiment: str
    rssd: float
    rssd_per_output: dict[str, float]
    offsets: dict[str, float]
    residuals: dict[str, np.ndarray]
    time: np.ndarray
    n_valid: dict[str, int]
    n_samples: int
    whitened: dict[str, np.ndarray] = field(default_factory=dict)


def experiment_fitness(exp: Experiment, t_sim, y_sim: dict[str, np.ndarray]) -> ExperimentFit:
    """Score a simulation of ``exp``: ``y_sim`` maps model outputs to trajectories on
    ``t_sim`` (the measured times inside the window, or any grid spanning them, which
    is then interpolated onto them), with the masked samples, weights and offset
    setting of ``exp`` applied."""
    data = exp.windowed_data()
    t_sim = np.asarray(t_sim, dtype=np.float64)
    t_meas = data.time
    if t_sim.ndim != 1 or t_sim.size < 2:
        raise SimulationError(f"{exp.name}: the simulation returned {t_sim.size} time point(s)")
    tol = 1e-9 * max(1.0, abs(t_sim[0]), abs(t_sim[-1]))
    if t_sim[0] > t_meas[0] + tol or t_sim[-1] < t_meas[-1] - tol:
        raise SimulationError(f"{exp.name}: the simulation spans {t_sim[0]:g} s to {t_sim[-1]:g} s "
                              f"but the samples to score span {t_meas[0]:g} s to {t_meas[-1]:g} s "
                              f"(did it stop early?)")
    scored = exp.scored
    outputs = scored.outputs
    for out in outputs:
        if out not in y_sim:
            raise ConfigError(f"the simulation of {exp.model} has no output '{out}'; it returned: "
                              f"{', '.join(y_sim) or '(nothing)'}",
                              str(exp.config_path), config_key("data.outputs", out))
    simulated = np.column_stack([np.asarray(y_sim[o], dtype=np.float64) for o in outputs])
    on_samples = t_sim is t_meas or (t_sim.shape == t_meas.shape and np.array_equal(t_sim, t_meas))
    if not (on_samples and np.all(np.isfinite(simulated))):  # interpolating would change nothing then
        simulated = sample_onto(t_sim, simulated, t_meas)
    fit = fit_outputs(scored.measured, simulated, scored.valid, scored.weights, exp.offset)
    n_valid = {o: int(n) for o, n in zip(outputs, fit.n_valid)}
    if is_whitened(exp):
        return _whitened_fit(exp, simulated, fit, n_valid)
    return ExperimentFit(
        experiment=exp.name,
        rssd=fit.rssd,
        rssd_per_output={o: float(v) for o, v in zip(outputs, fit.per_output)},
        offsets={o: float(c) for o, c in zip(outputs, fit.offset)},
        residuals={o: fit.residual[:, j] for j, o in enumerate(outputs)},
        time=t_meas,
        n_valid=n_valid,
        n_samples=sum(n for o, n in n_valid.items() if exp.weights[o] > 0),
    )


def _whitened_fit(exp: Experiment, simulated: np.ndarray, fit: Fit, n_valid: dict[str, int]) -> ExperimentFit:
    """:func:`experiment_fitness` of a whitened experiment (GLS offsets, whitened value)."""
    scored = exp.scored
    w = whitenings(exp)
    residuals, whitened, offsets, per_output = {}, {}, {}, {}
    for j, index, y in scored.columns:
        out = scored.outputs[j]
        r = (y - simulated[index, j])[None]
        c = float(w[j].offset(r)[0]) if exp.offset else 0.0
        e = w[j].residual(r, exp.offset)[0]
        full_r, full_e = np.full(simulated.shape[0], np.nan), np.full(simulated.shape[0], np.nan)
        full_r[index], full_e[index] = r[0] - c, e
        residuals[out], whitened[out], offsets[out] = full_r, full_e, c
        per_output[out] = float(np.mean(e * e))
    used = scored.weights > 0
    value = float(sum(scored.weights[j] * per_output[scored.outputs[j]] for j, _, _ in scored.columns)
                  / np.sum(scored.weights[used]))
    for j, out in enumerate(scored.outputs):  # outputs of weight zero: plain residuals, as unscored
        residuals.setdefault(out, fit.residual[:, j])
        offsets.setdefault(out, float(fit.offset[j]))
        per_output.setdefault(out, float(fit.per_output[j]))
    return ExperimentFit(exp.name, value, per_output, offsets, residuals, exp.windowed_data().time, n_valid,
                         sum(n for o, n in n_valid.items() if exp.weights[o] > 0), whitened)


def gaussian_log_likelihood(rssd, n_samples, sigma) -> np.ndarray:
    """Log-likelihood of each parameter set from its per-experiment RSSDs.

    Noise model: the measured samples are ``y = yhat(theta) + e`` with ``e`` independent
    Gaussian, zero mean, standard deviation ``sigma_e`` in experiment ``e``. Then

        log L(theta) = sum_e -0.5 * M_e * RSSD_e(theta) / sigma_e**2  + const

    with ``M_e`` the number of scored samples; the dropped constant is
    ``-sum_e M_e * log(sigma_e * sqrt(2 pi))``, which does not depend on theta because
    sigma is fixed. With a profiled offset (``offset = true``) the RSSD is that of the
    best offset; for a flat prior on the offset this equals the likelihood with the
    offset marginalised out, up to the theta-independent factor
    ``sqrt(2 pi sigma**2 / M)`` per output.

    The formula is exact for one output per experiment (the staged tests). With several
    outputs of different noise it is exact when their weights are ``M_k / sigma_k**2``
    and ``M_e / sigma_e**2`` is the sum of those weights.

    Samples are taken as independent: if the pre-step noise is correlated
    (``NoiseEstimate.phi`` well above 0) the likelihood is too sharp and posteriors too
    narrow. A non-finite RSSD (a failed simulation) gives ``-inf``.

    ``rssd``: (n, E); ``n_samples``, ``sigma``: (E,). Returns (n,).
    """
    r = np.asarray(rssd, dtype=np.float64)
    m = np.asarray(n_samples, dtype=np.float64)
    s = np.asarray(sigma, dtype=np.float64)
    if r.ndim != 2:
        raise ValueError(f"rssd must be (n, E), got shape {r.shape}")
    e = r.shape[1]
    if m.shape != (e,) or s.shape != (e,):
        raise ValueError(f"n_samples {m.shape} and sigma {s.shape} need one entry per "
                         f"experiment ({e})")
    if np.any(~np.isfinite(s)) or np.any(s <= 0) or np.any(m < 0):
        raise ValueError("sigma must be positive and finite and n_samples non-negative")
    with np.errstate(invalid="ignore"):
        terms = -0.5 * m * r / s ** 2
    ll = terms.sum(axis=1)
    ll[~np.all(np.isfinite(r), axis=1)] = -np.inf
    return ll
