"""iGrGen follows the Modelica language, not one compiler's reading of it: a second,
independent front end (rumoca, PyPI) compiles every test bench and every diagnosed
model, and GGOV1's flags are the Integers the language requires of a comparison with
``==`` (MLS section 3.5), set as Integers by every runner."""

from __future__ import annotations

import numpy as np
import pytest

from rapid_cosim.errors import ConfigError, ParameterError


def _models(repo):
    for folder in ("TestBenches", "Diagnosed"):
        for path in sorted((repo / "modelica" / "iGrGen" / folder).glob("*.mo")):
            if path.stem != "package":
                yield path, f"iGrGen.{folder}.{path.stem}"


def test_a_second_front_end_compiles_every_bench_and_diagnosed_model(repo):
    rumoca = pytest.importorskip("rumoca", reason="rumoca (the test extra) is the second Modelica front end")
    failed = {}
    for path, name in _models(repo):
        try:
            rumoca.Session(roots=[str(repo / "modelica")]).load(str(path), model=name)
        except Exception as e:  # rumoca's CompileError and ParseError
            failed[name] = str(e).splitlines()[0]
    assert not failed, failed


def test_the_second_front_end_refuses_a_real_compared_with_equality(tmp_path):
    """The check can fail: GGOV1's flags as they were (Reals compared with ==)."""
    rumoca = pytest.importorskip("rumoca", reason="rumoca (the test extra) is the second Modelica front end")
    source = ("model Flagged\n  parameter Real Rselect = 1;\n  Real x(start = 0, fixed = true);\n"
              "equation\n  der(x) = if Rselect == 1 then 1 else 0;\nend Flagged;\n")
    with pytest.raises(Exception, match="(?i)equality"):
        rumoca.Session().loads(source, model="Flagged")
    rumoca.Session().loads(source.replace("Real Rselect", "Integer Rselect"), model="Flagged")


def test_ggov1s_flags_are_integers_that_every_runner_sets(fmus):
    from rapid_cosim.simulator import get_simulator

    sim = get_simulator(fmus["StagedTestGGOV1"])
    assert sim.fmu.parameters["gov.Rselect"].type == "Integer" and sim.fmu.parameters["gov.Flag"].type == "Integer"
    final = {}
    for runner in ("exponential", "compiled", "python"):
        for rselect in (1, -1, 0):
            pm = sim.simulate({"gov.Rselect": rselect}, stop_time=60.0, output_interval=0.5, runner=runner)["pm"]
            final[runner, rselect] = pm
    for rselect in (1, -1, 0):  # the runners agree on each flag...
        assert np.max(np.abs(final["compiled", rselect] - final["python", rselect])) < 1e-9
        assert np.max(np.abs(final["exponential", rselect] - final["python", rselect])) < 1e-4
    # ... and the flag is obeyed: isochronous (0) restores the power, a droop does not
    assert abs(final["python", 0][-1] - final["python", 1][-1]) > 0.05
    assert abs(final["python", -1][-1] - final["python", 1][-1]) > 0.01
    with pytest.raises(ParameterError, match="not a whole number"):
        sim.simulate({"gov.Rselect": 0.5}, stop_time=1.0)


def test_a_flag_cannot_be_estimated(fmus, tmp_path):
    from rapid_cosim.experiment import experiment_from_arrays
    from rapid_cosim.fitting.problem import check_parameters
    from rapid_cosim.simulator import get_simulator

    t = np.arange(0.0, 20.0, 0.1)
    exp = experiment_from_arrays("g", "iGrGen.TestBenches.StagedTestGGOV1", t, {"pm": np.full(t.size, 0.7)},
                                 estimate={"gov.Rselect": (-1, 1)})
    with pytest.raises(ConfigError, match=r"Integer parameter .*\(a flag") as e:
        check_parameters(exp, get_simulator(fmus["StagedTestGGOV1"]).fmu.parameters)
    assert 'estimate."gov.Rselect"' in str(e.value)
