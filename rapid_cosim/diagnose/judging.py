"""The adequacy sequence, written once: the recorder's noise fitted to the campaign
(:func:`~rapid_cosim.noise.campaign_noise`), each test's floor
(:func:`~.selection.noise_floors`), the noise replicates of the null
(:func:`~.null.replicates_for`, made once and kept, as every fit of a campaign is
judged against the same draws), and a fit's residuals with their Jacobians judged
against them (:func:`~.adequacy.adequacy`).

The diagnosis's candidates (:mod:`.context`), the standard structures
(:mod:`rapid_cosim.structures.select`) and the fleet's playback of a record on file
(:mod:`rapid_cosim.fleet.playback`) all judge through a :class:`Judge`; an
architecture test refuses the sequence written by hand anywhere else."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Mapping, Sequence

import numpy as np

from ..experiment import Experiment
from ..noise import NoiseFit, campaign_noise
from .adequacy import Adequacy, adequacy
from .candidates import ExperimentResiduals, jacobian_at
from .null import REPLICATES, KeptReplicates, NoiseReplicates, replicates_for
from .selection import NoiseFloor, noise_floors


@dataclass
class Judge:
    """A campaign's noise as its fits are judged against it: per test the recorder's
    fitted model and its floor, and once made (:meth:`replicate`) the null's replicates."""

    noise_fits: dict[str, NoiseFit]
    floors: dict[str, NoiseFloor]
    null: NoiseReplicates | None = None

    @classmethod
    def of(cls, experiments: Sequence[Experiment], noise_fits: Mapping[str, NoiseFit] | None = None) -> "Judge":
        """For ``experiments`` (training and held-out alike: one noise model for both),
        with the caller's noise fits where it has them."""
        experiments = list(experiments)
        fits = noise_fits if noise_fits else campaign_noise(experiments)
        return cls(dict(fits), noise_floors(experiments, fits))

    def replicate(self, scored: Sequence[Experiment], replicates: int = REPLICATES, *, seed: int = 0,
                  kept: KeptReplicates | None = None, engine=None) -> NoiseReplicates:
        """The null's replicates of ``scored`` (whitened as the fitness whitens them),
        made on the first call; later calls give the same ones."""
        if self.null is None:
            self.null = replicates_for(list(scored), self.noise_fits, replicates, seed=seed, kept=kept, engine=engine)
        return self.null

    def judge(self, tests: Mapping[str, ExperimentResiduals], jacobians: Mapping[str, np.ndarray] | None = None,
              training: Sequence[str] = ()) -> Adequacy:
        """Does the fit whose residuals are ``tests`` leave only the noise? ``jacobians``:
        of its whitened residuals at its optimum (None: nothing was fitted); ``training``:
        the tests it was fitted on."""
        if self.null is None:
            raise RuntimeError("judged before the null's replicates were made (Judge.replicate first): a bug")
        return adequacy(tests, self.floors, self.null, jacobians, list(training))


def jacobians_at(*parts) -> dict[str, np.ndarray]:
    """Per test, the Jacobian of its whitened residual (:func:`~.candidates.jacobian_at`)
    over each ``(inputs, x)`` of ``parts`` (the training tests at the fit, the held-out
    ones at the same calibration), a failed step's entries as zero (no share of the noise)."""
    jac = {}
    for inputs, x in parts:
        jac.update(jacobian_at(inputs, np.asarray(x, dtype=float)))
    return {k: np.nan_to_num(v) for k, v in jac.items()}
