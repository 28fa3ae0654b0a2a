"""A governor record put back into a grid simulator nobody here wrote, in closed loop.

ANDES 2.0 (the ``test`` extra) reads the Kundur two-area case from PSS/E files
(``kundur/kundur.raw`` and ``kundur_full.dyr``), with generator 1's own TGOV1 replaced by
the record's text: ANDES's parser reads the ``.dyr`` line as it is written, builds its
model from it and runs a grid event (a constant-power load switched on or off, as
generate.py's events), so the rotor swing closes the loop through the network. What the
tests and ``make bench-replay`` compare is what ANDES does with the file.

Where ANDES departs from the PSS/E block diagram a record is written for, the values
ANDES read are converted before the run, each named (``ANDES.md`` beside this file has the
measurements behind them; :func:`departures` applies them):

- **IEEEG1's UO and UC** are not converted to the system base (K, PMAX, PMIN are): a
  machine-base rate must be given as Uo x Sn / Sb to mean what PSS/E means.
- **IEEEG1's K1..K8** are normalised to sum to one. PSS/E uses them as written. A record
  whose stages sum to S != 1 is given to ANDES as the same turbine with its valve scaled
  by S: stages K_i / S, and K, PMAX, PMIN, Uo, Uc times S (the valve's opening is then S
  times PSS/E's, every stage's power the same).
- **TGOV1** is PSS/E's since ANDES's pull request #207 (2021: the reference before the
  gain); its valve is a non-windup lag, its damping Dt on the speed deviation, as PSS/E's.
  Nothing is converted.
- **GAST** is PSS/E's (a low-value gate of the droop's demand and the temperature limit,
  a non-windup fuel valve, the fuel system's lag, the temperature's lag): read from the
  ``.dyr`` by ANDES's parser, nothing converted.
- **TGOV1D** (TGOV1 with a deadband, PowerWorld's and ORNL GridKit's layout: TGOV1's
  fields, then dbH, dbL and Trate) has no entry in ANDES's ``.dyr`` reader, though ANDES
  has the block: TGOV1DB, TGOV1 with ANDES's DeadBand1 (the no-step form) on the speed
  deviation. So its numbers are read here by PowerWorld's field list
  (:data:`POWERWORLD_LAYOUTS`, not this project's reader) and given to a TGOV1DB on
  generator 1; dbH is ANDES's dbU, dbL its dbL, in pu of speed on both sides.
- HYGOV (ANDES's gate integrator lacks PSS/E's 1/(r Tr) gain; its HYGOVDB too) and GGOV1
  (ANDES 2.0 has none: its parser builds a TGOV1 from the R field alone) are not put back:
  no trusted simulator here runs them (tests/test_block_diagrams.py checks them against
  their own block diagrams instead).
"""

from __future__ import annotations

import re
import tempfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np

SB, SN, F_NOM = 100.0, 900.0, 60.0  # the case's system base, generator 1's MVA base, the grid's frequency
GENERATOR = (1, "1")  # generator 1: bus 1, machine 1
STEP = 0.005  # ANDES's time step (s)
# layouts ANDES's .dyr reader lacks, by PowerWorld's field list: (ANDES's block, its fields)
POWERWORLD_LAYOUTS = {"TGOV1D": ("TGOV1DB", ("R", "T1", "VMAX", "VMIN", "T2", "T3", "Dt", "dbH", "dbL", "Trate"))}


@dataclass(frozen=True)
class GridEvent:
    """A constant-power load of ``mw`` at ``bus`` switched on (``load`` +1) or off (-1, the
    case's own bus-7 load PQ_1 lowered by as much first, so the dispatch is the same)."""

    load: int = 1
    bus: int = 7
    mw: float = 200.0
    t_event: float = 10.0
    duration: float = 60.0


def kundur_dyr(record: str) -> str:
    """The case's dynamic data with generator 1's TGOV1 replaced by ``record`` (a .dyr
    record's text for bus 1, machine 1)."""
    import andes

    full = Path(andes.get_case("kundur/kundur_full.dyr")).read_text()
    records = [r for r in full.split("/") if r.strip()]
    kept = [r for r in records if not re.match(r"\s*1\s+'TGOV1'\s+1\s", r)]
    if len(kept) != len(records) - 1:
        raise RuntimeError("kundur_full.dyr no longer holds one TGOV1 on generator 1")
    return " /\n".join(kept) + " /\n" + record


def andes_record(model: str, values: dict[str, float]) -> str:
    """A plant's ``.dyr`` record composed from ANDES's own field list (its
    ``io/psse-dyr.yaml``), not this project's writer: the plant stays independent of the
    exchange code a replay checks. ``values`` by ANDES's names (UO, UC; machine base);
    every field must be given (BUS2 and ID2 of IEEEG1 default to 0)."""
    import andes
    import yaml

    fields = yaml.safe_load((Path(andes.__file__).parent / "io" / "psse-dyr.yaml").read_text())[model]["inputs"]
    given = {"BUS2": 0, "ID2": 0, **values, "BUS": GENERATOR[0]}
    missing = [f for f in fields[2:] if f not in given]
    if missing:
        raise ValueError(f"{model} needs {', '.join(missing)}")
    return f"{GENERATOR[0]} '{model}' {GENERATOR[1]} " + " ".join(repr(float(given[f])) if f not in ("BUS2", "ID2")
                                                               else str(int(given[f])) for f in fields[2:]) + " /\n"


def powerworld_record(model: str, values: dict[str, float]) -> str:
    """A plant's record in a PowerWorld layout ANDES's reader lacks (TGOV1D), composed from
    PowerWorld's field list, not this project's writer."""
    _, fields = POWERWORLD_LAYOUTS[model]
    return (f"{GENERATOR[0]} '{model}' {GENERATOR[1]} " + " ".join(repr(float(values.get(f, 0.0))) for f in fields)
            + " /\n")


def powerworld_block(record: str) -> tuple[str, dict[str, float]] | None:
    """ANDES's block and parameters for a record in a layout of :data:`POWERWORLD_LAYOUTS`
    (None for any other record): its numbers read by PowerWorld's field list."""
    tokens = re.findall(r"'[^']*'|\S+", record.split("/")[0])
    model = tokens[1].strip("'\"").strip().upper()
    if model not in POWERWORLD_LAYOUTS:
        return None
    block, fields = POWERWORLD_LAYOUTS[model]
    numbers = [float(x.replace("D", "E")) for x in tokens[3:]]
    if len(numbers) != len(fields):
        raise ValueError(f"{model} takes {len(fields)} values ({' '.join(fields)}), the record has {len(numbers)}")
    given = dict(zip(fields, numbers))
    if given.pop("Trate") != 0.0:
        raise ValueError(f"{model} on a turbine rating other than the machine base is not converted here")
    given["dbU"] = given.pop("dbH")
    return block, given


def departures(ss) -> dict[str, dict[str, float]]:
    """Convert, in ANDES's model of generator 1's governor, what ANDES reads differently
    from PSS/E (module docstring); returns the conversions made (parameter -> (read, given))."""
    if not hasattr(ss, "IEEEG1") or ss.IEEEG1.n == 0:
        return {}
    model = ss.IEEEG1
    idx = model.idx.v[0]
    read = {name: float(getattr(model, name).vin[0]) for name in
            ("K", "UO", "UC", "PMAX", "PMIN", "K1", "K2", "K3", "K4", "K5", "K6", "K7", "K8")}
    total = sum(read[f"K{i}"] for i in range(1, 9))
    given = {"UO": read["UO"] * SN / SB * total, "UC": read["UC"] * SN / SB * total}
    if not np.isclose(total, 1.0, rtol=0, atol=1e-12):
        given.update({"K": read["K"] * total, "PMAX": read["PMAX"] * total, "PMIN": read["PMIN"] * total,
                      **{f"K{i}": read[f"K{i}"] / total for i in range(1, 9)}})
    for name, value in given.items():
        model.set(name, idx, value, base="device")
    return {name: (read[name], value) for name, value in given.items()}


def run_record(record: str, event: GridEvent) -> dict[str, np.ndarray]:
    """ANDES's closed-loop run of ``event`` with ``record`` as generator 1's governor:
    time, generator 1's speed (pu), electrical power ``pe`` and governor output ``pout``
    (pu on the machine base), and ``departures``, the conversions made."""
    import andes

    # no log file: ANDES would make a fresh /tmp/andes-* folder per call and log every step in it
    andes.config_logger(stream_level=40, file=False, log_path=tempfile.gettempdir())
    block = powerworld_block(record)
    with tempfile.TemporaryDirectory(prefix="rapid_cosim_andes_") as tmp:
        dyr = Path(tmp) / "kundur_unit.dyr"
        dyr.write_text(kundur_dyr("" if block else record))
        ss = andes.load(andes.get_case("kundur/kundur.raw"), addfile=str(dyr), setup=False, no_output=True,
                        default_config=True)
        if ss is None:
            raise RuntimeError("ANDES did not load the case with the record")
        if block:  # a layout ANDES's reader lacks: its block added on generator 1 (module docstring)
            ss.add(block[0], {"idx": "TG_record", "syn": _generator_1(ss), **block[1]})
        ss.add("PQ", {"idx": "PQ_ev", "bus": event.bus, "p0": event.mw / SB, "q0": 0.0,
                      "u": 1 if event.load < 0 else 0})
        ss.add("Toggle", {"idx": "TG_ev", "model": "PQ", "dev": "PQ_ev", "t": event.t_event})
        ss.setup()
    ss.Toggle.set_status("Toggle_1", 0)  # the case's own line trip: not this event
    if event.load < 0:
        ss.PQ.set("p0", "PQ_1", ss.PQ.get("p0", "PQ_1") - event.mw / SB, base="device")
    converted = departures(ss)
    ss.PQ.config.p2p, ss.PQ.config.p2z, ss.PQ.config.q2q, ss.PQ.config.q2z = 1, 0, 1, 0
    ss.PFlow.run()
    ss.TDS.config.tf, ss.TDS.config.tstep, ss.TDS.config.no_tqdm = event.duration, STEP, 1
    ss.TDS.run()
    if ss.exit_code != 0:
        raise RuntimeError(f"ANDES did not finish the event (exit code {ss.exit_code})")
    machine = _generator_1(ss)
    governor = next(m for m in (ss.TGOV1, ss.IEEEG1, ss.GAST, ss.TGOV1DB) if m.n and machine in list(m.syn.v))
    k = list(governor.syn.v).index(machine)
    ts = ss.dae.ts
    t, keep = np.unique(ts.t, return_index=True)  # an event time may be written twice
    out = {"t": t, "w": ts.x[keep, ss.GENROU.omega.a[0]], "pe": ts.y[keep, ss.GENROU.Pe.a[0]] * SB / SN,
           "pout": ts.y[keep, governor.pout.a[k]] * SB / SN, "model": type(governor).__name__,
           "departures": converted}
    if out["model"] == "IEEEG1":  # the valve as ANDES holds it (machine base; times S where the stages sum to S)
        out["valve"] = ts.x[keep, governor.IAW_y.a[k]] * SB / SN
    return out


def _generator_1(ss) -> str:
    """ANDES's idx of generator 1's machine."""
    return ss.GENROU.idx.v[list(ss.GENROU.bus.v).index(GENERATOR[0])]
