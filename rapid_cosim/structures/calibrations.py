"""Every structure's calibration for the selection (:mod:`.select`), each fitted whole in
one worker process, and an optional variant screened from its structure's optimum first.

**Screening (issue 54).** A structure's optional variants (:meth:`Structure.optional_variants
<.structure.Structure.optional_variants>`: IEEEG1 with its valve rates or its deadband free)
took most of an identification's structure simulations (the electrical unit's four IEEEG1
variants 11,500 of 14,400 at 7176f80), though most free a part the tests never reach. So a variant is
fitted after its structure, in the same worker: first a *screen*, Levenberg-Marquardt from
the structure's optimum (its freed parts where the structure holds them) and from a small
design of the freed parts around it, and one start from the box; then, only where the
screen comes within reach of mattering, the variant's own multistart over the whole box,
the better of the two kept. Within reach: the screen gains at least :data:`REACH` on the
structure in the criterion's data term. A variant matters to the record where it wins by
the selection threshold (10 and its parts' ``ln n``) or where the data lean to it (a
likelihood-ratio gain of 3.84 for one part at 5 %, :func:`rapid_cosim.identify.workflow._moved_by`);
the screen was found to fall short of the whole search by up to 9 where a rate binds (the
field unit's IEEEG1 with both rates), and is then far past REACH. A variant whose screen
gains less is kept as the screen left it: a fit the record never takes.

Only the multistart method (``ms``) is screened, and only without further ``searches``;
any other run fits every variant whole, as before.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from pathlib import Path
from typing import Sequence

import numpy as np

from ..calibration import RunOptions, best_run, inputs_from_experiments
from ..compiler.source import ModelSource
from ..diagnose.candidates import residuals_at
from ..diagnose.judging import Judge
from ..diagnose.selection import score
from ..errors import ParameterError
from ..experiment import Experiment
from ..fitting.engine import WholeFits, collected, fit_here, map_fits
from ..simulator import get_simulator
from .structure import Structure, on_structure

REACH = 2.0  # the data-term gain of a variant's screen on its structure from which it is searched whole
SCREEN = {"n_starts": 1, "rounds": 1, "screen": 0, "waves": 1}  # the screen's multistart, besides its vary


class Calibrations:
    """Every structure's calibration: (result, archive) of each, by :func:`_calibrate_all`
    when asked for (:meth:`runs`), or started at once (``start``) on a pool of their own
    where the options give local workers (:meth:`EngineSpec.start
    <rapid_cosim.fitting.engine.EngineSpec.start>`), so that the caller's other work (an
    identification's explanation) runs meanwhile. Either way a structure and its variants
    are fitted whole in one process, pinned, and give the same numbers. :meth:`close`
    stops a started pool whose results are not wanted (the caller failed): its fits are
    killed where they are, and their archives are resumed by the next run (with a word on
    the locks taken over)."""

    def __init__(self, structures: Sequence[Structure], training: Sequence[Experiment], fitted_noise: dict,
                 options: RunOptions, workdir: str | Path, searches: Sequence[str] = (),
                 source: ModelSource = ModelSource(), start: bool = False):
        self.structures = list(structures)
        self._args = (self.structures, list(training), fitted_noise, options, Path(workdir), tuple(searches), source)
        self._key = _key(structures, training, options, workdir, searches, source)
        self._started = None
        families = _families(self.structures)
        if start and options.engine.processes and len(families) > 1:
            payload = _worker_payload(*self._args)
            # the richest structures first: they take the most simulations
            first = sorted(range(len(families)), key=lambda k: -len(self.structures[families[k][0]].estimate))
            self._started = map_fits(options.engine, payload, first=first, start=True)

    def made_for(self, structures, training, options: RunOptions, workdir, searches, source: ModelSource) -> bool:
        """Whether these are the calibrations of ``structures`` on ``training`` with these
        options, work folder, searches and models."""
        return self._key == _key(structures, training, options, workdir, searches, source)

    def runs(self) -> list[tuple]:
        """Each structure's (result, archive), in the order given."""
        started, self._started = self._started, None
        runs = collected(started) if started is not None else None
        return _in_order(self.structures, runs) if runs is not None else _calibrate_all(*self._args)

    def close(self) -> None:
        if self._started is not None:
            self._started.close()
            self._started = None


def start_checked(calibrations: Calibrations | None, structures, training, fitted_noise, options: RunOptions,
                  workdir: Path, searches, source: ModelSource) -> Calibrations:
    """The caller's calibrations where they were made for these, new ones where none were given."""
    if calibrations is None:
        return Calibrations(structures, training, fitted_noise, options, workdir, searches, source)
    if not calibrations.made_for(structures, training, options, workdir, searches, source):
        raise ParameterError("the calibrations given were started for other structures, tests or options: start "
                             "them with these (Calibrations(structures, training, ...))")
    return calibrations


def _key(structures, training, options: RunOptions, workdir, searches, source: ModelSource) -> tuple:
    """What a selection's calibrations are made for, comparable."""
    return ([s.name for s in structures], [e.name for e in training], options, Path(workdir), tuple(searches),
            source)


def _families(structures: Sequence[Structure]) -> list[tuple[int, ...]]:
    """The structures' indices grouped as fitted together: a structure, then those of its
    variants given with it (a variant given without its structure is a family alone)."""
    names = {s.name for s in structures}
    families: dict[str, list[int]] = {}
    for k, s in enumerate(structures):
        families.setdefault(s.base if s.base in names else s.name, []).append(k)
    return [tuple(sorted(f, key=lambda k: structures[k].base is not None)) for f in families.values()]


def _in_order(structures: Sequence[Structure], by_family: list[list[tuple]]) -> list[tuple]:
    """The families' runs back in the structures' order."""
    out: list = [None] * len(structures)
    for family, runs in zip(_families(structures), by_family):
        for k, run in zip(family, runs):
            out[k] = run
    return out


def _worker_payload(structures, training, fitted_noise, options: RunOptions, workdir: Path, searches,
                    source: ModelSource) -> WholeFits:
    """What a worker fitting whole families takes: their benches built here first (once,
    not per worker), the options' engine one worker in that process."""
    benches = sorted({b for s in structures for b in (s.bench, s.input_bench) if b})
    source.build(benches)
    families = tuple(tuple(structures[k] for k in f) for f in _families(structures))
    return WholeFits(_calibrated_family, families, (list(training), fitted_noise, workdir, tuple(searches), source),
                     replace(options, engine=options.engine.single()))


def _calibrate_all(structures, training, fitted_noise, options: RunOptions, workdir: Path, searches,
                   source: ModelSource) -> list[tuple]:
    """Every structure's (result, archive), each family fitted whole in one worker process
    where the options give several local workers, else here with the options' engine. Why
    whole fits in workers: a structure's batches are a few dozen simulations each, and
    sending each batch to a pool cost more than it saved (an identification of the
    electrical unit took 28 s on 2 workers, 15 s in one process)."""
    families = tuple(tuple(structures[k] for k in f) for f in _families(structures))
    shared = (list(training), fitted_noise, workdir, tuple(searches), source)
    if not options.engine.processes or len(families) < 2:
        return _in_order(structures, fit_here(WholeFits(_calibrated_family, families, shared, options)))
    return _in_order(structures, map_fits(options.engine, _worker_payload(structures, training, fitted_noise,
                                                                          options, workdir, searches, source)))


def _calibrated_family(family: tuple[Structure, ...], shared: tuple, options: RunOptions) -> list[tuple]:
    """Worker: a structure's (result, archive), then each of its variants' (screened)."""
    runs, searches = [_calibrated(family[0], shared, options)], shared[3]
    if len(family) == 1:
        return runs
    if options.method != "ms" or searches:  # screened only by ms without searches
        return runs + [_calibrated(v, shared, options) for v in family[1:]]
    head = _Head.of(family[0], runs[0][0], shared)
    return runs + [_screened(v, head, shared, options) for v in family[1:]]


def _calibrated(s: Structure, shared: tuple, options: RunOptions) -> tuple:
    """One structure's (result, archive), by its own search over the whole box."""
    training, fitted_noise, workdir, searches, source = shared
    inputs = inputs_from_experiments(on_structure(s, training, fitted_noise), source=source)
    return best_run(inputs, options, workdir / f"{s.name}.h5", searches, replace_stale=True)


@dataclass(frozen=True)
class _Head:
    """What every variant's screen takes from its structure's fit, made once a family: the
    structure, its fit, its start values for the freed parts (the bench's defaults), the
    noise floors and its data term."""

    structure: Structure
    fitted: object  # its EstimationResult
    defaults: dict[str, float]
    floors: dict
    data_term: float

    @classmethod
    def of(cls, structure: Structure, fitted, shared: tuple) -> "_Head":
        training, fitted_noise, _, _, source = shared
        inputs = inputs_from_experiments(on_structure(structure, training, fitted_noise), source=source)
        params = get_simulator(next(iter(inputs.fmus.values()))).parameters
        floors = Judge.of(training, fitted_noise).floors
        return cls(structure, fitted, {n: p.start for n, p in params.items() if p.start is not None}, floors,
                   score(residuals_at(inputs, fitted.x), floors)[0])


def _screened(variant: Structure, head: _Head, shared: tuple, options: RunOptions) -> tuple:
    """A variant's (result, archive): its screen from ``head``'s optimum, searched whole too
    where the screen comes within :data:`REACH` (module docstring)."""
    training, fitted_noise, workdir, _, source = shared
    freed = [n for n in variant.estimate if n not in head.structure.estimate]
    held = {n: head.defaults[n] for n in freed if n in head.defaults}
    start = {**head.fitted.best(), **held}  # the freed parts where the structure holds them
    estimate = {n: replace(spec, start=float(np.clip(start[n], spec.min, spec.max))) if n in start else spec
                for n, spec in variant.estimate.items()}
    inputs = inputs_from_experiments(on_structure(replace(variant, estimate=estimate), training, fitted_noise),
                                     source=source)
    ms = {**options.estimator_options.get("ms", {}), **SCREEN, "vary": freed}
    screen = best_run(inputs, replace(options, estimator_options={**options.estimator_options, "ms": ms}),
                      workdir / f"{variant.name}.screen.h5", (), replace_stale=True)
    gain = head.data_term - score(residuals_at(inputs, screen[0].x), head.floors)[0]
    if gain < REACH:
        return screen
    whole = _calibrated(variant, shared, options)
    return min(screen, whole, key=lambda run: float(run[0].fun))
