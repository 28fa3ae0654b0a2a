"""The discrepancy workflow's parts that need no calibration: the criterion, the rules
of the verdict, the catalogue's generated benches, the residual features."""

import shutil

import numpy as np
import pytest

from rapid_cosim.compiler import build_models
from rapid_cosim.diagnose.candidates import CandidateFit, CandidateSpec, ExperimentResiduals
from rapid_cosim.diagnose.catalogue import CATALOGUE, bench_name, bench_source
from rapid_cosim.diagnose.selection import NoiseFloor, Ranked, bic, decide, settle_on_heldout
from rapid_cosim.noise import NoiseFit, RecorderNoise
from rapid_cosim.estimators.base import SearchSpace
from rapid_cosim.estimators.laplace import laplace
from rapid_cosim.simulator import Simulator


def _fit(label_effects, residuals, n_estimated):
    tests = {f"t{k}": ExperimentResiduals(f"t{k}", np.arange(r.size) * 0.1, r, float(np.mean(r ** 2)), 0.0, r.size)
             for k, r in enumerate(residuals)}
    return CandidateFit(CandidateSpec(label_effects), archive="-", model="-", parameters={}, n_estimated=n_estimated,
                        fitness=0.0, nfev=0, tests=tests)


def test_coloured_noise_does_not_favour_an_extra_parameter():
    """Noise only, white plus a slow component (as recorders have it). A candidate with
    one extra parameter (the least-squares coefficient of a slow step-like shape) always
    fits a little better. Taken as white, the criterion would often take it; whitened by
    the noise's own model, rarely."""
    n, wins_white, wins_whitened = 800, 0, 0
    model = RecorderNoise(0.001, ((0.0009, 1.5),), 0.1)
    shape = 1 - np.exp(-np.arange(n) * 0.1 / 5.0)
    white = NoiseFloor(NoiseFit.known(RecorderNoise(model.sigma, (), 0.1)))
    coloured = NoiseFloor(NoiseFit.known(model))
    for seed in range(20):
        rng = np.random.default_rng(seed)
        res = [model.sample(np.arange(n) * 0.1, rng) for _ in range(2)]
        fitted = [r - (r @ shape) / (shape @ shape) * shape for r in res]
        small, big = _fit((), res, 2), _fit(("delay",), fitted, 3)
        wins_white += bic(big, {"t0": white, "t1": white}) < bic(small, {"t0": white, "t1": white})
        wins_whitened += bic(big, {"t0": coloured, "t1": coloured}) < bic(small, {"t0": coloured, "t1": coloured})
    assert wins_white >= 8
    assert wins_whitened <= 3


def _ranked(**deltas):
    best = min(deltas.values())
    return sorted([Ranked(k, () if k == "none" else (k,), v, v - best, 0.0, {}, "") for k, v in deltas.items()],
                  key=lambda r: r.bic)


def test_verdict_names_a_decisive_effect():
    v = decide(_ranked(none=0.0, rate_limit=-200.0, delay=-150.0))
    assert v.effect == "rate_limit" and v.effects == ["rate_limit"]


def test_verdict_is_ambiguous_between_close_candidates():
    v = decide(_ranked(none=0.0, delay=-120.0, measurement_lag=-115.0))
    assert v.effect == "ambiguous" and set(v.candidates) == {"delay", "measurement_lag"}


def test_heldout_evidence_settles_a_training_tie_only_when_it_adds_up():
    ranking = _ranked(none=0.0, delay=-120.0, measurement_lag=-115.0)
    # delay ahead by 5 on training and by 7 on held-out data: 12 in all, named
    v = settle_on_heldout(decide(ranking), ranking, {"delay": 300.0, "measurement_lag": 307.0})
    assert v.effect == "delay" and v.effects == ["delay"] and "held-out" in v.said
    # the held-out tests favour the other by 16: measurement_lag leads by 11 in all
    v = settle_on_heldout(decide(ranking), ranking, {"delay": 316.0, "measurement_lag": 300.0})
    assert v.effect == "measurement_lag"
    # 5 + 3 = 8 is under the threshold: still ambiguous, and it says why
    v = settle_on_heldout(decide(ranking), ranking, {"delay": 300.0, "measurement_lag": 303.0})
    assert v.effect == "ambiguous" and set(v.candidates) == {"delay", "measurement_lag"}
    assert "do not separate" in v.said
    # none, with a caveat, is not a tie to settle: left alone
    tie = _ranked(none=0.0, backlash=-4.0, deadband=-2.0)
    v = decide(tie, not_excluded=["deadband"])
    assert settle_on_heldout(v, tie, {"none": 0.0, "deadband": 100.0}).effect == "none"


def test_an_effect_that_barely_beats_none_is_not_named():
    ranking = _ranked(none=0.0, backlash=-4.0, deadband=-2.0)
    assert decide(ranking).effect == "none"
    v = decide(ranking, not_excluded=["deadband"])  # a material deadband fits as well: a caveat, not a verdict
    assert v.effect == "none" and v.candidates == [] and "cannot exclude deadband at a material size" in v.said


def test_verdict_none_with_what_it_cannot_exclude():
    ranking = _ranked(none=0.0, deadband=7.0, delay=8.0)
    assert decide(ranking).effect == "none"
    v = decide(ranking, not_excluded=["deadband"])
    assert v.effect == "none" and "cannot exclude deadband" in v.said


def test_ambiguous_only_between_effects_that_each_beat_none():
    """delay beats none by 12, measurement_lag by 4: within 10 of each other, but only one
    is decisive against none, so it is named; both decisive, and within 10: ambiguous."""
    v = decide(_ranked(none=0.0, delay=-12.0, measurement_lag=-4.0))
    assert v.effect == "delay" and "does not itself beat none" in v.said
    v = decide(_ranked(none=0.0, delay=-22.0, measurement_lag=-14.0))
    assert v.effect == "ambiguous" and set(v.candidates) == {"delay", "measurement_lag"}


def test_laplace_recovers_a_known_gaussian():
    space = SearchSpace(("a", "b"), np.array([0.02, 0.1]), np.array([0.12, 20.0]), (False, True))
    mean = np.array([0.05, 3.0])
    cov = np.array([[1e-6, 2e-5], [2e-5, 1e-2]])
    precision = np.linalg.inv(cov)
    g = laplace(lambda X: 0.5 * np.einsum("ni,ij,nj->n", X - mean, precision, X - mean), space, mean)
    assert np.allclose(g.cov, cov, rtol=1e-3)


def test_generated_benches_equal_the_hand_written_ones(repo, tmp_path):
    pkg = tmp_path / "iGrGen"
    shutil.copytree(repo / "modelica" / "iGrGen", pkg)
    generated = {}
    for name in CATALOGUE:
        cls = f"iGrGen.Diagnosed.Generated{name.title().replace('_', '')}"
        (pkg / "Diagnosed" / f"{cls.rsplit('.', 1)[1]}.mo").write_text(bench_source([name], cls))
        generated[name] = cls
    built = {o.model: o.fmu for o in build_models(list(generated.values()) + [e.bench for e in CATALOGUE.values()],
                                                  package=pkg, fmu_dir=tmp_path / "fmus", log=lambda *_: None)}
    params = {"gov.Ts": 3.0, "src.t_return": 40.0}
    for name, cls in generated.items():
        a = Simulator(built[cls]).simulate(params, stop_time=60, output_interval=0.1)
        b = Simulator(built[CATALOGUE[name].bench]).simulate(params, stop_time=60, output_interval=0.1)
        assert np.array_equal(a["pm"], b["pm"]), name


def test_bench_names_and_errors():
    assert bench_name([]) == "iGrGen.TestBenches.StagedTest"
    assert bench_name(["delay"]) == CATALOGUE["delay"].bench
    assert bench_name(["rate_limit", "deadband"]) == bench_name(["deadband", "rate_limit"])
    with pytest.raises(ValueError, match="unknown effect"):
        bench_name(["friction"])
    text = bench_source(["rate_limit", "backlash"], "iGrGen.Diagnosed.X", values={"gov.R": 0.051})
    assert "Governors.TGTypeIValveEffects gov(R = 0.051)" in text


def test_laplace_never_evaluates_outside_the_bounds():
    space = SearchSpace(("db", "Ts"), np.array([0.0, 0.1]), np.array([0.1, 20.0]), (False, True))
    seen = []

    def nll(X):
        seen.append(X.copy())
        return 0.5 * ((X[:, 0] - 0.0) / 0.01) ** 2 + 0.5 * ((np.log(X[:, 1]) - np.log(3.0)) / 0.1) ** 2

    g = laplace(nll, space, np.array([0.0, 3.0]))  # db at its lower bound
    points = np.vstack(seen)
    assert np.all(points >= space.lower) and np.all(points <= space.upper)
    assert g.at_bound == ("db",)
    assert np.isfinite(g.std).all()


def test_a_named_model_goes_into_the_users_package_never_the_shipped_one(tmp_path, monkeypatch):
    """Without --package (or $RAPID_COSIM_PACKAGE) the package is the one inside
    rapid_cosim, which in a virtual environment is writable: the model goes into the work
    folder's copy all the same. A package of the user's is written where it can be, its
    copy used where it cannot."""
    import os
    from types import SimpleNamespace

    from rapid_cosim.compiler.source import ModelSource
    from rapid_cosim.diagnose.workflow import written_into

    own, copy = tmp_path / "iGrGen", tmp_path / "work" / "package" / "iGrGen"
    (own / "Diagnosed").mkdir(parents=True)
    def ctx(users: bool):  # a diagnosis's sources: the user's (named, or the shipped one) and the work copy
        return SimpleNamespace(user_source=ModelSource(own if users else None), source=ModelSource(copy))

    monkeypatch.delenv("RAPID_COSIM_PACKAGE", raising=False)
    shipped = written_into(ctx(False))
    assert shipped[0] == copy and "copy of the shipped package" in shipped[1]
    assert written_into(ctx(True)) == (own, "")
    (own / "Diagnosed").chmod(0o500)
    try:
        if not os.access(own / "Diagnosed", os.W_OK):  # root may write anyway
            where, why = written_into(ctx(True))
            assert where == copy and "cannot be written" in why
    finally:
        (own / "Diagnosed").chmod(0o700)


def test_an_unexplained_or_ambiguous_diagnosis_is_saved_and_said_in_words(tmp_path):
    """The outcome constants are the words themselves: h5py stores them (a str Enum member
    it refused, and an identification whose explanation was unexplained ended in a
    TypeError), and the verdict's sentence says 'unexplained', not a class name."""
    import h5py
    import json

    from rapid_cosim.diagnose.catalogue import AMBIGUOUS, UNEXPLAINED, VerdictKind
    from rapid_cosim.diagnose.adequacy import Adequacy
    from rapid_cosim.diagnose.result import AdequacyJudgement, Diagnosis, DiagnosisVerdict, SearchCertainty, SearchReport
    from rapid_cosim.diagnose.limits import verdict_text
    from rapid_cosim.diagnose.selection import Verdict

    for effect in (UNEXPLAINED, AMBIGUOUS):
        v = Verdict(effect, candidates=["delay", "deadband"], reason="nothing fits")
        said = verdict_text(v, type("Fit", (), {"adequate": False})())
        assert said in ("unexplained", "ambiguous + unexplained remainder") and "VerdictKind" not in said
        unfit = Adequacy(False, 2.0, 0.001, 0.05, 100, ())
        d = Diagnosis(DiagnosisVerdict(effect, [], list(v.candidates), v.said, said, [], None, None),
                      AdequacyJudgement(unfit, unfit, {"final": unfit}, None, {}), SearchReport([], [], SearchCertainty({}, [], "", 3, 2.0), {}, {}),
                      {}, {}, {}, {}, {}, {}, {}, {}, None, None, {}, ["t1"], [], "now")
        js, h5 = d.save(tmp_path / effect)
        with h5py.File(h5) as f:
            assert f.attrs["effect"] == effect
        written = json.loads(js.read_text())
        assert written["effect"] == effect and written["adequate"] is False
        assert written["candidate_adequacy"] == {"final": {"adequate": False, "p": 0.001, "pooled_variance_ratio": 2.0}}
        assert list(written)[:6] == ["effect", "effects", "candidates", "reason", "verdict", "adequate"]
        assert VerdictKind.of(effect) is VerdictKind(effect) and f"{VerdictKind.of(effect)}" == effect
    assert VerdictKind.of("rate_limit") is VerdictKind.NAMED
