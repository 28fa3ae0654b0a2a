"""How a run is made beyond its experiments (method, seed, workers, runner, estimator
options), kept in its archive; and the ``METHOD.NAME=VALUE`` overrides of the CLI."""

from __future__ import annotations

import warnings
from dataclasses import asdict, dataclass, field, fields
from typing import Any, Mapping, Sequence

from ..fitting.engine import EngineSpec
from ..errors import RapidCosimError
from ..estimators.chain import REGISTRY, parse_method
from ..fitting.objective import PENALTY
from ..simulator import DEFAULT_RUNNER, check_runner


@dataclass(frozen=True)
class RunOptions:
    """How a run is made, beyond its configs: kept in the archive (the engine's three
    settings flat, as archives have always held them)."""

    method: str = "pf:10+nm"
    seed: int = 1
    engine: EngineSpec = EngineSpec()
    penalty: float = PENALTY
    estimator_options: dict[str, dict[str, Any]] = field(default_factory=dict)  # {"pf": {"n_particles": 50}}
    runner: str = DEFAULT_RUNNER  # which simulator runner produced the run (see rapid_cosim.simulator)

    def to_json(self) -> dict:
        # the keys in the order archives have always held them
        return {"method": self.method, "seed": self.seed, "n_jobs": self.engine.n_jobs,
                "backend": self.engine.backend, "penalty": self.penalty,
                "estimator_options": asdict(self)["estimator_options"], "runner": self.runner,
                "scheduler": self.engine.scheduler}

    def check(self) -> "RunOptions":
        """Every option valid (method, estimator options, runner; the engine checked itself
        when it was built), so that a bad one is refused before an archive is created or a
        plan announced."""
        try:
            parse_method(self.method)
            stage_options(self)
        except (ValueError, TypeError) as e:
            raise RapidCosimError(str(e)) from None
        check_runner(self.runner)
        return self

    @classmethod
    def from_json(cls, data: Mapping) -> "RunOptions":
        known = {f.name for f in fields(cls)}
        values = {k: v for k, v in data.items() if k in known and k != "engine"}
        values.setdefault("runner", "python")  # archives from before the compiled runner
        engine = {f.name: data[f.name] for f in fields(EngineSpec) if f.name in data}
        try:
            spec = EngineSpec(**engine)
        except RapidCosimError as e:  # a backend an older version ran: where a run goes does not change it
            warnings.warn(f"the archived engine {engine} is not one this version runs ({e}); it runs in this "
                          "process unless --n-jobs/--joblib-backend say otherwise", stacklevel=2)
            spec = EngineSpec()
        return cls(**values, engine=spec)


def parse_option_overrides(items: Sequence[str]) -> dict[str, dict[str, Any]]:
    """``["pf.n_particles=50", "nm.max_fev=200"]`` -> nested dict, checked against the
    methods' option classes so that a typo fails before any simulation."""
    out: dict[str, dict[str, Any]] = {}
    for item in items or []:
        key, sep, raw = item.partition("=")
        method, dot, name = key.strip().partition(".")
        if not sep or not dot:
            raise RapidCosimError(f"--option expects METHOD.NAME=VALUE (e.g. pf.n_particles=50), got {item!r}")
        if method not in REGISTRY:
            raise RapidCosimError(f"--option {key}: unknown method {method!r}; methods: {', '.join(REGISTRY)}")
        options_cls = REGISTRY[method][1]
        allowed = [f.name for f in fields(options_cls)]
        if name not in allowed:
            raise RapidCosimError(f"--option {key}: {method} has no option {name!r}; options: {', '.join(allowed)}")
        out.setdefault(method, {})[name] = _parse_value(raw.strip())
    return out


def _parse_value(raw: str):
    lowered = raw.lower()
    if lowered in ("none", "null"):
        return None
    if lowered in ("true", "false"):
        return lowered == "true"
    for kind in (int, float):
        try:
            return kind(raw)
        except ValueError:
            pass
    return raw


def stage_options(options: RunOptions) -> dict:
    out = {}
    for m, kw in options.estimator_options.items():
        if m not in REGISTRY:
            raise ValueError(f"options for an unknown method {m!r}; methods: {', '.join(sorted(REGISTRY))}")
        cls = REGISTRY[m][1]
        known = [f.name for f in fields(cls)]
        unknown = [k for k in kw if k not in known]
        if unknown:
            raise ValueError(f"{m} has no option {unknown[0]!r}; its options: {', '.join(known)}")
        out[m] = cls(**kw)
    return out
