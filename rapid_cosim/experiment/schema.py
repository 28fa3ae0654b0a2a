"""Every key of every TOML file a user writes for rapid-cosim, declared once.

Why declared here and not in each parser: the parsers take their accepted keys from these
declarations (:mod:`.config`, :mod:`.signals`, :mod:`.recording`, :mod:`.recorder`,
``identify.unit``, ``fleet.spec``, ``validation.tolerances``), and ``docs/config.md`` is
generated from them, so the page and the parsers cannot disagree. Allowed values and
defaults that live in a module reading its keys from here are written again below (that
module cannot be imported here without a cycle); ``tests/test_config_reference.py`` holds
them equal. Layers above ``experiment`` import this module; it imports none of them, so
the unit, structure, fleet and tolerance files are declared here as data.

    rapid-cosim docs config > docs/config.md     # regenerates docs/config.md
"""

from __future__ import annotations

import json
import re
from dataclasses import dataclass

from ..data.csv_table import DECIMALS, DELIMITERS
from ..data.readers import TIME_UNITS

PAGE = "docs/config.md"
REQUIRED = "required"


@dataclass(frozen=True)
class Key:
    """One key: ``default`` and ``allowed`` are the page's words (:func:`lit` for a value)."""

    name: str
    type: str
    unit: str = ""
    default: str = REQUIRED
    allowed: tuple | str = ""
    doc: str = ""


@dataclass(frozen=True)
class Section:
    """A TOML table; ``<word>`` in ``name`` stands for a name the user chooses. ``open``:
    the entry of a table whose keys are such names ([fixed] parameters, [inputs] model
    inputs); ``strict``: whether its parser refuses a key it does not list."""

    name: str
    keys: tuple[Key, ...]
    doc: str
    open: Key | None = None
    strict: bool = True

    @property
    def names(self) -> frozenset[str]:
        return frozenset(k.name for k in self.keys)

    def anchor(self, key: Key) -> str:
        """``inputs.<input>.gaps`` and ``max`` -> ``inputs.input.gaps.max``."""
        return re.sub(r"<(\w+)>", r"\1", f"{self.name}.{key.name}")


@dataclass(frozen=True)
class FileKind:
    """One kind of file; ``strict``: whether its parser refuses a section it does not list."""

    title: str
    file: str
    doc: str
    sections: tuple[Section, ...]
    strict: bool = True

    def accepted(self) -> dict[str, frozenset[str] | None]:
        """Top-level section -> its accepted keys (None: names the user chooses), in order."""
        return {s.name: None if s.open else s.names for s in self.sections if "." not in s.name}

    def section(self, name: str) -> Section:
        return next(s for s in self.sections if s.name == name)


def lit(value) -> str:
    """A default as TOML writes it."""
    return f"`{json.dumps(value)}`"


# ------------------------------------------------------------------ the experiment config

STR, NUM, TABLE, STRS = "string", "number", "table", "array of strings"
UNITS = ("", "1", "pu", "Hz", "mHz", "kHz", "MW", "kW", "W", "GW", "Mvar", "s", "rad/s", "Hz/s", "mHz/s")
CONVERSIONS = ("none", "deviation", "deviation_pu")
BASELINES = ("none", "pre-event", "detrend")
FLAG_KINDS = ("c37.118", "valid")
FILLS = ("linear",)
SCALES = ("linear", "log")
UNIT_DOC = "the column's unit; the value is scaled to its dimension's base (mHz to Hz, kW to MW)"
OFF = "> 0, or `false`"

EXPERIMENT = Section("experiment", (
    Key("name", STR, "", "the config file's folder name", "letters, digits, `_`, `-`, `.`; first not `-` or `.`",
        "the experiment's name: its archive group and its `<parameter>@<name>` search dimensions"),
    Key("model", STR, "", "required, or `fmu`", "a class of the package, or a file ending `.fmu`",
        "the test bench (`iGrGen.TestBenches.StagedTest`), built into an FMU; a `.fmu` is read as `fmu`"),
    Key("fmu", STR, "", "instead of `model`", "a file ending `.fmu`",
        "any FMI 2.0 or 3.0 FMU, relative to the config's folder; give `model` or `fmu`, not both"),
    Key("description", STR, "", lit(""), "", "free text about the test"),
), "The model and the experiment's name.")

DATA = Section("data", (
    Key("file", STR, "", REQUIRED, "`.csv`, `.mat`, `.h5` (`run.h5:/group`), `.cfg`/`.cff` (COMTRADE)",
        "the recording, relative to the config's folder"),
    Key("time", STR, "", lit("time"), "", "the time column (not read with `timestamp`)"),
    Key("timestamp", STR, "", "none", "a CSV column", "absolute timestamps (a PMU export): time is then seconds from "
        "`event_time`"),
    Key("event_time", "string or number", "s", "the first row's timestamp", "only with `timestamp`",
        "time zero: a timestamp as the file writes it, or epoch seconds"),
    Key("outputs", TABLE, "", REQUIRED, "at least one; output -> column, or `[data.outputs.<output>]`",
        "the model outputs compared, each with its data column (`pe`: electrical power, needs `mach.H`)"),
    Key("resample", NUM, "s", "none", "> 0; not with `flags`", "every column interpolated linearly onto a regular grid "
        "of this step from the first sample"),
    Key("time_unit", STR, "", lit("s"), tuple(TIME_UNITS), "the time column's unit"),
    Key("flags", TABLE, "", "none", "`[data.flags]`", "a quality column: the frames it marks invalid are masked"),
    Key("limits", TABLE, "", "every check on", "`[data.limits]`", "values no recorder can mean, masked"),
    Key("delimiter", STR, "", "detected", DELIMITERS, "the CSV files' field separator"),
    Key("decimal", STR, "", lit("."), DECIMALS, "the CSV files' decimal separator; `\",\"` needs another delimiter"),
), "The recording and how to read it.")

OUTPUT = Section("data.outputs.<output>", (
    Key("column", STR, "", REQUIRED, "", "the data column"),
    Key("unit", STR, "", lit(""), UNITS, UNIT_DOC),
    Key("scale", NUM, "", lit(1.0), "not with `rating`", "multiplies the value"),
    Key("offset", NUM, "", lit(0.0), "", "added after `scale`"),
    Key("rating", NUM, "MVA", "none", "> 0; with a `unit` of power (MW, kW, W, GW); not with `scale`",
        "the unit's rating: the power becomes per unit (scale = 1 / rating)"),
), "An output given as a table: `scale * (column * unit factor) + offset` is compared. A power unit needs `rating` "
   "or `scale`.")

DATA_FLAGS = Section("data.flags", (
    Key("column", STR, "", REQUIRED, "", "the quality column"),
    Key("kind", STR, "", lit("c37.118"), FLAG_KINDS,
        "`c37.118`: a STAT word, bits 15-14 (data error) or 13 (sync lost) mark a frame invalid; `valid`: 0 does"),
), "A frame marked invalid is masked in every column.")

DATA_LIMITS = Section("data.limits", (
    Key("frequency", "number or false", "Hz", lit(5.0), OFF, "a frequency outside nominal +- this"),
    Key("rocof", "number or false", "Hz/s", lit(20.0), OFF, "a frequency's one- or two-frame spike steeper than this"),
    Key("power", "number or false", "x rating", lit(2.0), OFF, "a power beyond +- this x the rating"),
    Key("power_step", "number or false", "x rating", lit(0.5), OFF,
        "a power's one- or two-frame spike of more than this x the rating per frame"),
), "Samples masked with a warning naming their rows; `false` turns a check off. A frequency is an input converted "
   "from a Hz unit about a nominal of 40 to 70 Hz; a power is an output with a rating; a spike goes out and back.")

INPUTS = Section("inputs", (), "Model inputs driven by measured columns (recorded events).",
                 open=Key("<input>", TABLE, "", "none", "an input of the model (`f_dev`, `dw`, `rocof`, ...)",
                          "the column that drives it: `[inputs.<input>]`"))

INPUT = Section("inputs.<input>", (
    Key("column", STR, "", REQUIRED, "", "the data column"),
    Key("file", STR, "", "`[data] file`", "", "another data file on the same time base, relative to the config"),
    Key("time", STR, "", lit("time"), "", "the time column of `file` (read only with `file`)"),
    Key("unit", STR, "", lit(""), UNITS, UNIT_DOC),
    Key("convert", STR, "", lit("none"), CONVERSIONS, "`deviation`: value - nominal; `deviation_pu`: (value - "
        "nominal) / nominal"),
    Key("nominal", NUM, "the unit's base", "none", "needed by a conversion; not 0 with `deviation_pu`",
        "the value the deviation is taken from (Hz for a `mHz` column)"),
    Key("scale", NUM, "", lit(1.0), "", "multiplies the converted value"),
    Key("offset", NUM, "", lit(0.0), "", "added after `sign` and `scale`"),
    Key("sign", NUM, "", lit(1), "1 or -1", "flips the input"),
    Key("baseline", STR, "", lit("none"), BASELINES,
        "removes the mean (`pre-event`) or a straight line (`detrend`) of the samples before `baseline_end`"),
    Key("baseline_end", NUM, "s", "`[fitness] pre_step_end`", "needed by a baseline", "the end of the quiet samples"),
    Key("gaps", TABLE, "", "holes up to 0.25 s bridged", "`[inputs.<input>.gaps]`", "the longest hole bridged"),
), "The value given to the model: `sign * scale * converted(column * unit factor) + offset`, minus the baseline. "
   "Inputs are linear between samples.")

GAPS = Section("inputs.<input>.gaps", (
    Key("max", NUM, "s", REQUIRED, "(0, 60]; below 0.25 read as 0.25", "the longest hole bridged"),
    Key("fill", STR, "", lit("linear"), FILLS, "how a hole is bridged"),
), "A masked or missing input sample is bridged, never fed to the model; the outputs near a hole longer than 0.25 s "
   "leave the fit, and a hole longer than `max` is an error.")

FIXED = Section("fixed", (
    Key("documented", STR, "", "none", "a `.dyr` or `.dyd` record file", "each `gov.*` constant of the unit's PSS/E or "
        "PSLF record (relative to this file), written out when read; values stated here win, and an estimated one "
        "starts from the record's"),
), "FMU parameter values held fixed. Unquoted dotted keys (`gov.R = 0.05`) are read as the quoted name.",
    open=Key("<parameter>", NUM, "", "none", "a parameter of the model, without `@`; `mach.H` 0.5 to 15 s, `mach.D` "
             "0 to 5 pu", "the value it is held at"))

ESTIMATE = Section("estimate", (), "The parameters to estimate. A parameter estimated in several experiments of a "
                   "joint fit is one dimension and must be declared the same in each.",
                   open=Key("<parameter>", TABLE, "", "none", "a Real parameter of the model, without `@`, not also "
                            "fixed", "one search dimension: `[estimate.<parameter>]`"))

ESTIMATE_ENTRY = Section("estimate.<parameter>", (
    Key("min", NUM, "", REQUIRED, "< `max`; > 0 with `scale = \"log\"`", "the lower bound"),
    Key("max", NUM, "", REQUIRED, "> `min`", "the upper bound"),
    Key("label", STR, "", "the parameter's name", "", "its name in tables and figures"),
    Key("scale", STR, "", lit("linear"), SCALES, "`log`: moved by its logarithm (a positive range spanning decades)"),
    Key("start", NUM, "", "the midpoint (geometric with `log`)", "within [min, max]", "the initial guess"),
    Key("per_experiment", "boolean", "", lit(False), "", "one dimension per experiment, `<parameter>@<experiment>`"),
), "One estimated parameter.")

FITNESS = Section("fitness", (
    Key("window", "array", "s", "the whole record", "[start, end], start < end; over the record by at most one sample "
        "interval", "the span compared"),
    Key("weights", TABLE, "", "1.0 each", "output -> number >= 0; one > 0", "each output's weight"),
    Key("offset", "boolean", "", lit(False), "", "profile out a constant measurement offset per output"),
    Key("noise", "string, number or table", "pu", "none", "`\"pre-step\"`, a number > 0, or output -> number > 0 for "
        "every output", "the noise sigma of a Gaussian likelihood; `\"pre-step\"`: estimated before `pre_step_end`"),
    Key("pre_step_end", NUM, "s", "none", "inside the record; needed by `noise = \"pre-step\"`",
        "the end of the quiet samples before the step (and the inputs' `baseline_end`)"),
), "What is compared and how it is scored.")

SIMULATION = Section("simulation", (
    Key("start_time", NUM, "s", lit(0.0), "<= the first sample used", "when the simulation starts"),
    Key("stop_time", NUM, "s", "the last sample in the window", ">= the last sample used", "when the simulation stops"),
    Key("output_interval", NUM, "s", "half the median sample interval in the window (3 digits)",
        "> 0; not longer than the simulation", "the fine grid simulated, then sampled onto the measured times"),
    Key("timeout", NUM, "s", lit(30.0), "> 0", "wall-clock seconds one simulation may take"),
    Key("communication_step", NUM, "s", "the measured samples and input rows", "> 0",
        "Co-Simulation FMUs only: the largest communication step (the fixed one where the FMU cannot vary it)"),
), "How each simulation runs.")

NOISE = Section("noise", (), "The recorder's noise model of each compared output: the fitness becomes the least "
                "squares of residuals whitened by it. With one, every output of positive weight needs one.",
                open=Key("<output>", TABLE, "", "none", "an output of `[data] outputs`", "`[noise.<output>]`"))

NOISE_MODEL = Section("noise.<output>", (
    Key("white", NUM, "pu", lit(0.0), ">= 0", "the standard deviation of the white part"),
    Key("dt", NUM, "s", REQUIRED, "within 10 % of the output's median sample interval", "the recorder's interval"),
    Key("components", "array of tables", "", lit([]), "`[noise.<output>.components]`; white > 0 or one component",
        "the slow (Ornstein-Uhlenbeck) parts"),
), "One output's noise model.")

NOISE_COMPONENT = Section("noise.<output>.components", (
    Key("sigma", NUM, "pu", REQUIRED, "> 0", "its standard deviation"),
    Key("tau", NUM, "s", REQUIRED, "> 0", "its correlation time"),
), "One slow component (an entry of the list).")

CONFIG = FileKind("Experiment config", "config.toml", "One file per experiment (`experiments/test1/config.toml`), "
                  "read by rapid_cosim/experiment/config.py; relative paths are taken from its folder. A mistake is an "
                  "error naming the file and the key.",
                  (EXPERIMENT, DATA, OUTPUT, DATA_FLAGS, DATA_LIMITS, INPUTS, INPUT, GAPS, FIXED, ESTIMATE,
                   ESTIMATE_ENTRY, FITNESS, SIMULATION, NOISE, NOISE_MODEL, NOISE_COMPONENT))

# ------------------------------------------------------------------ the other files

UNIT_FILE = FileKind("Unit file", "unit.toml", "A unit folder's file (rapid_cosim/identify/unit.py): the unit's tests, "
                     "the held-out ones, the structures its record may take. Paths are relative to it.", (
    Section("unit", (
        Key("name", STR, "", "the unit's folder name", "", "the unit's name in the story and the report"),
        Key("kind", STR, "", "none", ("steam", "gas", "hydro"), "the kind of plant: without `[structures]`, the unit "
            "gets the shipped standard structures of its kind (steam TGOV1, IEEEG1; gas GAST, GGOV1; hydro HYGOV)"),
        Key("mva", NUM, "MVA", "none", "1 to 5000", "the machine's MVA base; a PSLF `.dyd` record needs it"),
        Key("bus", "integer", "", lit(1), "1 to 999999", "the record's bus in the grid operator's case"),
        Key("machine_id", STR, "", lit("1"), "", "the machine's id at that bus"),
    ), "The unit and where its record goes."),
    Section("tests", (
        Key("configs", STRS, "", REQUIRED, "at least one; folders or `config.toml` files", "the unit's experiments"),
        Key("holdout", STRS, "", lit([]), "names of experiments of `configs`", "kept out of the fits, to confirm it"),
    ), "The staged tests and recorded events."),
    Section("structures", (
        Key("files", STRS, "", "none", "existing structure files", "structure files the record may take"),
        Key("standard", STRS, "", "none", "TGOV1, IEEEG1, GGOV1, HYGOV, GAST, TGTypeI",
            "shipped standard structures the record may take, by name"),
    ), "The structure files (below). Without this section: the shipped standard structures of the unit's `kind`; "
       "with no kind, the unit's own `structures/<name>.toml` of the standard names where it has that folder, "
       "else every shipped standard structure."),
))

STRUCTURE_FILE = FileKind("Structure file", "structures/<name>.toml", "One governor structure (rapid_cosim/"
                          "structures/structure.py). `[fixed]` and `[estimate]` (required) are the experiment config's, "
                          "checked when the file is read (errors name it); `documented` is relative to this file.", (
    Section("structure", (
        Key("name", STR, "", REQUIRED, "", "the structure's name (`TGOV1`)"),
        Key("bench", STR, "", REQUIRED, "a model of the package", "the staged tests' bench"),
        Key("input_bench", STR, "", "none", "a model of the package", "the recorded events' bench; needed when a test "
            "is driven by recorded inputs"),
    ), "The benches a test runs on with this structure."),
    FIXED, ESTIMATE, ESTIMATE_ENTRY,
    Section("optional", (), "Parts freed only where the data call for them (IEEEG1's valve rates).",
            open=Key("<parameter>", TABLE, "", "none", "not also fixed or estimated", "`[optional.<parameter>]`")),
    Section("optional.<parameter>", (
        Key("carries", STR, "", lit("optional"), "an effect of the catalogue (`rate_limit`, `deadband`)",
            "what the optional part carries: the parts of one effect are freed together and apart, each effect's "
            "on its own"), *ESTIMATE_ENTRY.keys,
    ), "An `[estimate]` entry and what it carries."),
))

FLEET_FILE = FileKind("Fleet file", "fleet.toml", "The units of one grid event (rapid_cosim/fleet/spec.py). Paths are "
                      "relative to it.", (
    Section("fleet", (
        Key("name", STR, "", "the fleet file's folder name", "not empty", "the fleet's name"),
        Key("units", STRS, "", REQUIRED, "at least one; each names folders with a `unit.toml`",
            "unit folders, or globs of them; their names must differ"),
        Key("records", STR, "", "none", "a `.dyr` or `.dyd` file",
            "the units' records on file, each found by bus and machine id; a unit's own `record.dyr` comes first"),
        Key("tolerances", STR, "", "the default bands", "a tolerance file", "the validation bands (below)"),
    ), "The only section, required."),
))

METRIC_TERMS: dict[str, tuple[str, ...]] = {  # each metric's band terms, in the report's order
    "rmse": ("relative", "noise", "absolute"), "peak_change": ("relative", "noise", "absolute"),
    "settled_change": ("relative", "noise", "absolute"), "rise_time": ("relative", "seconds"),
    "time_to_peak": ("relative", "seconds"), "settling_time": ("relative", "seconds"),
}
_BANDS = {"rmse": ("{ noise = 2.0, relative = 0.05 }", "the RMSE of the compared output"),
          "peak_change": ("{ relative = 0.1, noise = 3.0 }", "the error of the peak change"),
          "settled_change": ("{ relative = 0.1, noise = 3.0 }", "the error of the settled change"),
          "rise_time": ("{ relative = 0.1, seconds = 1.0 }", "the error of the rise time (90 %)"),
          "time_to_peak": ("{ relative = 0.1, seconds = 1.0 }", "the error of the time to peak"),
          "settling_time": ("{ relative = 0.2, seconds = 2.0 }", "the error of the settling time")}

TOLERANCE_FILE = FileKind("Tolerance file", "<name>.toml", "The validation report's bands "
                          "(rapid_cosim/validation/tolerances.py, `rapid-cosim report --tolerances`; docs/tolerances.toml "
                          "holds the defaults), in a file of its own or a larger one.", (
    Section("validation", tuple(Key(m, TABLE, "", f"`{band}`", "terms: " + ", ".join(METRIC_TERMS[m]), doc)
                                for m, (band, doc) in _BANDS.items()),
            "Required. A metric not named keeps its default; `metric = {}` judges nothing for it."),
    Section("validation.<metric>", (
        Key("relative", NUM, "", "none", "> 0 and <= 1", "a share of the measured value (the settled change for rmse)"),
        Key("noise", NUM, "noise levels", "none", "> 0 and <= 100", "a multiple of the test's noise level"),
        Key("absolute", NUM, "pu", "none", "> 0 and <= 10", "pu of the compared output"),
        Key("seconds", NUM, "s", "none", "> 0 and <= 600", "for the times"),
    ), "A band is the largest of its terms that can be evaluated; each metric takes the terms listed above."),
), strict=False)

KINDS = (CONFIG, UNIT_FILE, STRUCTURE_FILE, FLEET_FILE, TOLERANCE_FILE)


# ------------------------------------------------------------------ the page and its links

def _slug(heading: str) -> str:
    """GitHub's anchor of a heading."""
    return re.sub(r"[^\w\- ]", "", heading.strip().lower()).replace(" ", "-")


def _title(section: Section) -> str:
    return f"`[{section.name}]`"


def _cell(text: str) -> str:
    """Markdown table cell text: ``|`` escaped, and ``<`` outside code (it would open HTML)."""
    parts = str(text).replace("|", "\\|").split("`")
    return "`".join(p if i % 2 else p.replace("<", "&lt;") for i, p in enumerate(parts))


def _allowed(allowed) -> str:
    return ", ".join(f"`{json.dumps(v)}`" for v in allowed) if isinstance(allowed, tuple) else allowed


def reference_markdown() -> str:
    """docs/config.md: a table per section, an anchor per key (``#data.delimiter``)."""
    out = ["# Config reference", "",
           ("<!-- Generated from rapid_cosim/experiment/schema.py by "
            "`rapid-cosim docs config > docs/config.md`: edit that, not this. -->"), "",
           ("Every key of every TOML file rapid-cosim reads, as its parser reads it: the type, the unit, the default, "
            "the values allowed and what it does. The parsers take their keys from the same declarations, so a key "
            "is here exactly when it is accepted. `<output>`, `<parameter>` and the like stand for names you choose; "
            "each key has an anchor such as `#data.delimiter` or `#estimate.parameter.min`."), ""]
    out += [f"- [{k.title}](#{_slug(f'{k.title}: `{k.file}`')})" for k in KINDS]
    done: set[str] = set()
    for kind in KINDS:
        rule = " Other sections are refused." if kind.strict else " Other sections are not read."
        out += ["", f"## {kind.title}: `{kind.file}`", "", kind.doc + rule]
        for s in kind.sections:
            if s.name in done:
                out += ["", f"- {_title(s)}: as [in the experiment config](#{_slug(_title(s))})."]
                continue
            done.add(s.name)
            rule = "" if s.open or not s.strict else " Other keys are refused."
            out += ["", f"### {_title(s)}", "", s.doc + rule + ("" if s.strict else " Other keys are not read."), "",
                    "| key | type | unit | default | allowed | what it does |", "|---|---|---|---|---|---|"]
            for k in (*s.keys, *((s.open,) if s.open else ())):
                cells = (f'<a id="{s.anchor(k)}"></a>`{k.name}`', k.type, k.unit, k.default, _allowed(k.allowed),
                         k.doc)
                out.append("| " + " | ".join(_cell(c) if i else c for i, c in enumerate(cells)) + " |")
    return "\n".join(out) + "\n"


def _segments(key: str) -> list[str]:
    """``estimate."gov.R".min`` -> ``["estimate", "gov.R", "min"]`` (list indices dropped)."""
    return [m.group(1) if m.group(1) is not None else m.group(2)
            for m in re.finditer(r'"((?:[^"\\]|\\.)*)"|([^."\[\]]+)', re.sub(r"\[\d+\]", "", key))]


def _matches(pattern: str, segments: list[str]) -> bool:
    parts = _segments(pattern)
    return len(parts) == len(segments) and all(p.startswith("<") or p == s for p, s in zip(parts, segments))


def _entry(key: str) -> tuple[str, Key | None] | None:
    """(the page's anchor, the key's entry) of a config key as errors name it
    (``data.delimiter``, ``estimate."gov.R".min``), the nearest enclosing entry where the
    key has none of its own (a section: no Key); None if none."""
    segments = _segments(key)
    while segments:
        for kind in KINDS:
            for s in kind.sections:
                if len(segments) == 1 and s.name == segments[0]:
                    return _slug(_title(s)), None
                if _matches(s.name, segments[:-1]):
                    hit = next((k for k in s.keys if k.name == segments[-1]), s.open)
                    if hit is not None:
                        return s.anchor(hit), hit
        segments = segments[:-1]
    return None


def reference(key: str) -> str | None:
    """The link to the page's entry of a config key as errors name it, falling back to
    the nearest enclosing entry; None if none."""
    found = _entry(key)
    return None if found is None else f"{PAGE}#{found[0]}"


def explain(key: str) -> str | None:
    """What an error says of the key it names: what the key allows and its default, and
    its entry on the page (which an installed rapid-cosim prints with ``rapid-cosim docs
    config``); None if the page has no entry for it."""
    found = _entry(key)
    if found is None:
        return None
    anchor, entry = found
    where = f"{PAGE}#{anchor}; 'rapid-cosim docs config' prints the page"
    if entry is None:
        return where
    allowed = _allowed(entry.allowed).replace("`", "")
    words = "; ".join(w for w in (allowed and f"allowed: {allowed}",
                                  entry.default not in (REQUIRED, "") and f"default {entry.default}") if w)
    return f"{words}; {where}" if words else where
