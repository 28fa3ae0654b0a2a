"""A steam unit with a binding opening rate, recorded in three grid events (issue 40).

The plant: ANDES 2.0's IEEEG1 on generator 1 (900 MVA) of the Kundur two-area grid, as
ANDES reads it from a PSS/E record composed from ANDES's own field list
(``../electrical/andes_grid.py``): K 20, K1 0.3, K3 0.7, T3 0.1 s, T4 0.3 s, T5 8 s, a
0.5 s governor lag (T1) and an opening rate Uo of 0.015 pu/s (machine base) that binds
on every load switched on; the rest as ``../electrical/generate.py``'s IEEEG1 events
(PMAX 1.2). Three events, each 90 s at 5 ms steps, the event 30 s in (the quiet span the
recorder's noise is estimated from):

- ``steam_on``: 200 MW switched on at bus 7 (area 1);
- ``steam_off``: 200 MW switched off at bus 7 (another load lowered by as much first);
- ``steam_on9``: 150 MW switched on at bus 9 (area 2, across the tie): held out.

Recorded as generate.py records: generator 1's electrical power (MW) and speed as the
frequency (Hz) at 30 frames/s with the same recorder noise (each event its own draw).
The configs hold TG Type I's documented constants (the explanation's base, as the
electrical unit's); ``unit.toml`` names the structures TGOV1 and IEEEG1
(``../electrical/structures``). Each folder also keeps ``clean.csv`` (the same frames
without the noise) and ``truth.json`` (the plant, the event, what ANDES was given).
Run from the repository root::

    .venv/bin/python experiments/steam/generate.py
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent / "electrical"))

import andes_grid  # noqa: E402
import generate  # noqa: E402

PLANT = {"K": 20.0, "T1": 0.5, "T2": 0.0, "T3": 0.1, "UO": 0.015, "UC": -1.0, "PMAX": 1.2, "PMIN": 0.0,
         "T4": 0.3, "K1": 0.3, "K2": 0.0, "T5": 8.0, "K3": 0.7, "K4": 0.0, "T6": 0.5, "K5": 0.0, "K6": 0.0,
         "T7": 0.5, "K7": 0.0, "K8": 0.0}  # ANDES's names, machine base
T_EVENT, DURATION = 30.0, 90.0
EVENTS = {  # name -> (the grid event, the recorder's seed)
    "steam_on": (andes_grid.GridEvent(load=+1, bus=7, mw=200.0, t_event=T_EVENT, duration=DURATION), 51),
    "steam_off": (andes_grid.GridEvent(load=-1, bus=7, mw=200.0, t_event=T_EVENT, duration=DURATION), 52),
    "steam_on9": (andes_grid.GridEvent(load=+1, bus=9, mw=150.0, t_event=T_EVENT, duration=DURATION), 53),
}
HELD_OUT = "steam_on9"


def plant_record() -> str:
    return andes_grid.andes_record("IEEEG1", PLANT)


def recorded(run: dict, seed: int, noise: bool = True) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Time, frequency (Hz) and P_e (MW) at 30 frames/s, with the recorder's noise."""
    t = np.arange(0.0, DURATION + 1e-9, 1.0 / generate.RATE)
    f_noise, p_noise = generate.recorder_noise(t.size, np.random.default_rng(seed))
    f = generate.F_NOM * np.interp(t, run["t"], run["w"]) + noise * f_noise
    p = generate.SN * np.interp(t, run["t"], run["pe"]) + noise * p_noise
    return t, f, p


def config(name: str, event: andes_grid.GridEvent, p_ref: float) -> dict:
    """The event's config: TG Type I's documented constants, P_e recorded, H documented."""
    sections = generate.config(generate.Event(name, "TGTypeI"), p_ref)
    what = f"{event.mw:g} MW {'on' if event.load > 0 else 'off'} at bus {event.bus}"
    sections["experiment"]["description"] = (f"ANDES Kundur two-area, gen 1 a steam unit (IEEEG1, opening rate "
                                             f"binding): {what}, {event.t_event:g} s; P_e recorded")
    sections["fitness"]["pre_step_end"] = event.t_event
    return sections


def main() -> None:
    from rapid_cosim.experiment import render_config

    for name, (event, seed) in EVENTS.items():
        folder = HERE / name
        folder.mkdir(exist_ok=True)
        run = andes_grid.run_record(plant_record(), event)
        generate.write_data(folder / "data.csv", *recorded(run, seed))
        generate.write_data(folder / "clean.csv", *recorded(run, seed, noise=False))
        (folder / "config.toml").write_text(render_config(config(name, event, float(run["pout"][0]))))
        truth = {"plant": PLANT, "andes_names": True, "event": event.__dict__, "seed": seed,
                 "p_ref": float(run["pout"][0]), "departures": {k: list(v) for k, v in run["departures"].items()},
                 "andes": "2.0.0"}
        (folder / "truth.json").write_text(json.dumps(truth, indent=1) + "\n")
        print(folder, f"p_ref {truth['p_ref']:.4f}, governor response {np.ptp(run['pout']):.4f} pu")
    (HERE / "unit.toml").write_text(
        "# A steam unit with a binding opening rate (IEEEG1 in ANDES: K 20, K1 0.3, K3 0.7, T5 8, Uo 0.015 pu/s), three\n"
        "# grid events recorded as electrical power, one held out; made by generate.py. `make identify-steam`.\n"
        '[unit]\nname = "ANDES Kundur generator 1 (900 MVA), a steam unit, three grid events"\nmva = 900.0\n'
        'bus = 1\nmachine_id = "1"\n\n[tests]\n'
        f"configs = [{', '.join(repr(n).replace(chr(39), chr(34)) for n in EVENTS)}]\n"
        f'holdout = ["{HELD_OUT}"]\n\n'
        '[structures]\nfiles = ["../electrical/structures/TGOV1.toml", "../electrical/structures/IEEEG1.toml"]\n')


if __name__ == "__main__":
    main()
