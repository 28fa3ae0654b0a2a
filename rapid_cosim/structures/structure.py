"""A governor structure as its file describes it (``experiments/structures/TGOV1.toml``)::

    [structure]
    name = "TGOV1"
    bench = "iGrGen.TestBenches.StagedTestTGOV1"        # a staged test's model
    input_bench = "iGrGen.TestBenches.FrequencyInputTGOV1"  # a recorded event's (optional)

    [fixed]        # what the plant documentation gives for this structure
    documented = "unit.dyr"  # optional: its constants from the unit's .dyr/.dyd record (one
                             # it states, a TGOV1D's band say, is then no optional part)
    "gov.VMAX" = 1.0
    [estimate]     # what the tests must determine, with bounds
    "gov.R" = { min = 0.02, max = 0.12, label = "R" }
    [optional]     # parts freed only where the data call for them (IEEEG1's valve rates)

Each test's config keeps its data, source (``src.*``), dispatch (``gov.p_ref``), fitness
and simulation settings; its governor constants and estimates are the structure's
(:meth:`Structure.experiment`). Read and checked here, before any fit: the file's keys
and tables, and (:meth:`Structure.check`) its parameters against its benches. Selection
among structures is :mod:`.select`'s.
"""

from __future__ import annotations

import tomllib
from itertools import combinations
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Sequence

import numpy as np

from ..compiler.source import ModelSource
from ..diagnose.catalogue import EFFECTS
from ..errors import ConfigError, Finding
from ..exchange import model_named
from ..experiment import EstimateSpec, Experiment, documented, parse_experiment, render_config
from ..experiment.config import parameter_tables
from ..experiment.reader import load_toml
from ..experiment.schema import STRUCTURE_FILE
from ..simulator import get_simulator

KEPT_FIXED = ("src.", "gov.p_ref", "f_nom", "mach.")  # the test's and the unit's machine (H, D), not the governor's


@dataclass(frozen=True)
class Structure:
    name: str
    bench: str
    input_bench: str | None
    fixed: dict[str, float]
    estimate: dict[str, EstimateSpec]
    path: str
    optional: dict[str, EstimateSpec] = field(default_factory=dict)  # freed only where the data call for them
    carries: dict[str, str] = field(default_factory=dict)  # optional part -> the effect it carries ("rate_limit")
    base: str | None = None  # an optional variant's structure (:meth:`optional_variants`), None for a file's own

    @property
    def effects(self) -> tuple[str, ...]:
        """The effects the optional parts carry, in the file's order (IEEEG1: rate_limit,
        deadband)."""
        return tuple(dict.fromkeys(self.carries.get(n, "optional") for n in self.optional))

    def parts(self, effect: str) -> list[str]:
        """The optional parts that carry ``effect``."""
        return [n for n in self.optional if self.carries.get(n, "optional") == effect]

    def with_optional(self) -> "Structure":
        """This structure with all its optional parts estimated too."""
        return replace(self, name=f"{self.name}+{'+'.join(self.effects)}", optional={}, carries={},
                       estimate={**self.estimate, **self.optional})

    def optional_variants(self) -> list["Structure"]:
        """This structure with each non-empty set of the optional parts of one effect
        estimated too, effect by effect, the whole set first (IEEEG1's valve rates: both,
        the opening alone, the closing alone; then its deadband), named
        ``IEEEG1+rate_limit``, ``IEEEG1+rate_limit(Uo)`` and ``IEEEG1+deadband``. Why each
        apart: a rate the tests never reach is not determined by them, and a fit that frees
        it leaves it anywhere it does not bind there, a limit the record would then state
        for other events (a closing rate of 0.004 pu/s from a load switched on, say); the
        criterion keeps a part only where the data call for it. The parts of two effects are
        not freed together: a unit with both gets the one that wins, and the story says what
        the record then cannot carry. A variant is first screened from its structure's
        optimum, its freed parts searched around it, and searched by its own multistart over
        the whole box only where that screen comes within reach of mattering
        (:mod:`.calibrations`): started from the optimum alone, variants settled in worse
        optima where a rate binds (the field unit's IEEEG1 with both rates 9 apart in BIC, a
        fleet unit's T3 moved by 1.2 standard errors), so the screen only decides which
        variants are searched whole."""
        out = []
        for effect in self.effects:
            names = self.parts(effect)
            for k in range(len(names), 0, -1):
                for chosen in combinations(names, k):
                    tail = "" if k == len(names) else "(" + ",".join(n.removeprefix("gov.") for n in chosen) + ")"
                    out.append(replace(self, name=f"{self.name}+{effect}{tail}", optional={}, carries={},
                                       estimate={**self.estimate, **{n: self.optional[n] for n in chosen}},
                                       base=self.name))
        return out

    def freed_effect(self, fit_name: str) -> str | None:
        """The effect whose optional parts a fit of this structure freed (its variant's
        name, :meth:`optional_variants`; not :meth:`with_optional`'s, which frees every
        effect's), None for the plain fit."""
        head = fit_name.removeprefix(self.name + "+")
        if head == fit_name:
            return None
        return head.split("(")[0]

    def playing(self, record: dict[str, float]) -> tuple["Structure", dict[str, float]]:
        """This structure holding a record's values (iGrGen names) as a grid simulator plays
        them (:meth:`~rapid_cosim.exchange.tables.Model.played`: the record's fields win;
        this structure's constants fill only what the record has no field for), nothing
        optional, and the record's values of the parameters it estimates (bench names)."""
        values = model_named(self.name).played(record, self.fixed)
        missing = [n for n in self.estimate if n not in values]
        if missing:
            raise ConfigError(f"the record gives no value for {', '.join(missing)}, which {self.name} estimates",
                              self.path, "estimate")
        return (replace(self, fixed={k: v for k, v in values.items() if k not in self.estimate}, optional={}),
                {n: values[n] for n in self.estimate})

    @classmethod
    def load(cls, path: str | Path) -> "Structure":
        path = Path(path)
        raw, _ = load_toml(path, "the structure file")
        head = raw.get("structure")
        accepted = STRUCTURE_FILE.accepted()
        extra = sorted(set(raw) - set(accepted))
        if extra:
            raise ConfigError(f"unknown section(s) {', '.join(extra)}; allowed: {', '.join(accepted)}", str(path),
                              extra[0])
        for section in accepted:
            if section in raw and not isinstance(raw[section], dict):
                raise ConfigError(f"[{section}] must be a table (a section), got {raw[section]!r}", str(path), section)
        if not isinstance(head, dict) or "name" not in head or "bench" not in head:
            raise ConfigError("needs [structure] with name and bench", str(path), "structure")
        unknown = sorted(set(head) - accepted["structure"])
        if unknown:
            raise ConfigError(f"unknown key '{unknown[0]}'; allowed: {', '.join(sorted(accepted['structure']))}",
                              str(path), f"structure.{unknown[0]}")
        if not raw.get("estimate"):
            raise ConfigError("estimates nothing: give [estimate] with the parameters the tests must determine",
                              str(path), "estimate")
        fixed, estimate = dict(raw.get("fixed", {})), dict(raw["estimate"])
        recorded: set[str] = set()  # constants the unit's record gave
        if documented.KEY in fixed:  # a .dyr/.dyd record of the unit, relative to the structure file
            values, specs = parameter_tables(fixed, estimate, str(path))  # flat names; the file's own errors first
            estimate = {n: spec.to_config() for n, spec in specs.items()}
            _, added, starts, _ = documented.record_constants(fixed[documented.KEY], values, estimate, path.parent,
                                                              str(path))
            fixed, recorded = {**added, **values}, set(added)
            estimate = {n: {**v, "start": starts[n]} if n in starts else v for n, v in estimate.items()}
        optional = {k: dict(v) if isinstance(v, dict) else v for k, v in raw.get("optional", {}).items()}
        # what the unit's record documents is a constant, not a part to free: a TGOV1D's band
        optional = {k: v for k, v in optional.items() if k not in recorded}
        carries = {k: str(v.pop("carries", "optional")) for k, v in optional.items() if isinstance(v, dict)}
        return cls.from_tables(str(head["name"]), str(head["bench"]), head.get("input_bench"), fixed, estimate,
                               str(path), optional, carries)

    @classmethod
    def from_tables(cls, name: str, bench: str, input_bench: str | None, fixed: dict, estimate: dict, path: str,
                    optional: dict | None = None, carries: dict[str, str] | str = "") -> "Structure":
        """A structure from its file's tables as TOML reads them (``{"gov.R": {"min": ...}}``,
        dotted keys too), each checked as a config's are, errors naming ``path``."""
        values, specs = parameter_tables(fixed, estimate, path)
        _, free = parameter_tables({}, optional or {}, path, "optional")
        clash = sorted(set(free) & (set(specs) | set(values)))
        if clash:
            raise ConfigError(f"{', '.join(clash)}: optional and also fixed or estimated", path, "optional")
        if isinstance(carries, str):  # one effect for every optional part
            carries = {n: carries or "optional" for n in free}
        unknown = sorted({e for e in carries.values() if e not in EFFECTS and e != "optional"})
        if unknown:
            raise ConfigError(f"carries = {unknown[0]!r}: not an effect of the catalogue; allowed: "
                              f"{', '.join(EFFECTS)}", path, "optional")
        return cls(name, bench, input_bench, values, specs, path, free, {n: carries.get(n, "optional") for n in free})

    def check(self, *, source: ModelSource = ModelSource()) -> list[Finding]:
        """Every problem of this structure file that a run would meet, each naming this file
        and its key: a bench that cannot be built, a parameter its bench lacks or cannot
        take, a value outside the range the model declares."""
        from ..errors import BuildError

        out = []
        for key, bench in (("structure.bench", self.bench), ("structure.input_bench", self.input_bench)):
            if bench is None:
                continue
            try:
                params = get_simulator(source.fmu(bench)).parameters
            except (BuildError, ConfigError) as e:
                out.append(Finding(self.path, key, str(e)))
                continue
            tables = [("fixed", n, [v]) for n, v in self.fixed.items()]
            tables += [(section, n, [spec.min, spec.max]) for section, table in
                       (("estimate", self.estimate), ("optional", self.optional)) for n, spec in table.items()]
            for section, name, values in tables:
                where = f'{section}."{name}"'
                info = params.get(name)
                if info is None or not info.settable:
                    close = [k for k in params if k.rsplit(".", 1)[-1].lower() == name.rsplit(".", 1)[-1].lower()]
                    out.append(Finding(self.path, where, f"{bench} has no settable parameter '{name}'"
                                       + (f" (close: {', '.join(close)})" if close else "")))
                    continue
                lo = -np.inf if info.min is None else info.min
                hi = np.inf if info.max is None else info.max
                bad = [v for v in values if isinstance(v, (int, float)) and not lo <= v <= hi]
                if bad:
                    out.append(Finding(self.path, where, f"{bad[0]:g} is outside the range {bench} declares for "
                                       f"'{name}': [{lo:g}, {hi:g}]"))
        first = {}  # one problem per key, though both benches meet it
        for f in out:
            first.setdefault((f.file, f.where), f)
        return list(first.values())

    def experiment(self, exp: Experiment, noise=None) -> Experiment:
        """``exp`` with this structure as its model (``noise``: the recorder's model, for
        the whitened fitness)."""
        raw = tomllib.loads(exp.config_text)
        bench = self.input_bench if exp.inputs else self.bench
        if bench is None:
            raise ConfigError(f"{exp.name} is driven by recorded inputs; the structure {self.name} has no "
                              "input_bench", self.path, "structure.input_bench")
        fixed = {k: v for k, v in raw.get("fixed", {}).items() if k.startswith(KEPT_FIXED)}
        data = dict(raw["data"])
        data_file = Path(data["file"])
        data["file"] = str(data_file if data_file.is_absolute() else (Path(exp.config_path).parent / data_file))
        machine = {k: v for k, v in raw.get("estimate", {}).items() if k.startswith("mach.")}  # H estimated
        sections = {**raw, "experiment": {**raw["experiment"], "model": bench}, "data": data,
                    "fixed": {**fixed, **self.fixed},
                    "estimate": {**{n: s.to_config() for n, s in self.estimate.items()}, **machine}}
        if noise is not None:
            (output,) = [o for o in exp.outputs if exp.weights[o] > 0]
            sections["noise"] = {output: noise.to_config()}
        return parse_experiment(render_config(sections), exp.config_path, data=exp.data, files=exp.files)


def on_structure(structure: Structure, experiments: Sequence[Experiment], fitted_noise: dict) -> list[Experiment]:
    """The experiments as :func:`select_structure` fits and predicts them: ``structure``
    as their model, each whitened by its recorder's model of ``fitted_noise`` (a
    :func:`~rapid_cosim.noise.campaign_noise` over them); a report of a fit predicts its
    held-out tests from these."""
    return [structure.experiment(e, fitted_noise[e.name].model) for e in experiments]
