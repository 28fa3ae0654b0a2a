"""A unit whose plant runs in ANDES, recorded in grid events: what experiments/steam,
experiments/deadband and experiments/gas share (issues 40, 53).

The plant is generator 1 (900 MVA) of ANDES 2.0's Kundur two-area grid with the unit's
governor record (``andes_grid.py``: ANDES's own parser, or PowerWorld's field list for a
layout its parser lacks). Each event runs 90 s at 5 ms steps, the event 30 s in (the quiet
span the recorder's noise is estimated from), and is recorded as ``generate.py`` records:
generator 1's electrical power (MW) and speed as the frequency (Hz) at 30 frames/s with
the recorder's noise, each event its own draw. The configs hold TG Type I's documented
constants (the explanation's base, as the electrical unit's). Each folder also keeps
``clean.csv`` (the same frames without the noise) and ``truth.json`` (the plant, the
event, what ANDES was given).
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

import andes_grid
import generate

T_EVENT, DURATION = 30.0, 90.0


def grid_event(load: int, bus: int, mw: float) -> andes_grid.GridEvent:
    return andes_grid.GridEvent(load=load, bus=bus, mw=mw, t_event=T_EVENT, duration=DURATION)


def three_events(prefix: str, first_seed: int) -> dict[str, tuple[andes_grid.GridEvent, int]]:
    """The steam unit's three events (name -> (event, the recorder's seed)): 200 MW switched
    on at bus 7 (area 1), 200 MW switched off there (another load lowered by as much first),
    150 MW switched on at bus 9 (area 2, across the tie); seeds from ``first_seed``."""
    events = (("on", +1, 7, 200.0), ("off", -1, 7, 200.0), ("on9", +1, 9, 150.0))
    return {f"{prefix}_{name}": (grid_event(load, bus, mw), first_seed + k)
            for k, (name, load, bus, mw) in enumerate(events)}


def recorded(run: dict, seed: int, noise: bool = True) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Time, frequency (Hz) and P_e (MW) at 30 frames/s, with the recorder's noise."""
    t = np.arange(0.0, DURATION + 1e-9, 1.0 / generate.RATE)
    f_noise, p_noise = generate.recorder_noise(t.size, np.random.default_rng(seed))
    f = generate.F_NOM * np.interp(t, run["t"], run["w"]) + noise * f_noise
    p = generate.SN * np.interp(t, run["t"], run["pe"]) + noise * p_noise
    return t, f, p


def config(name: str, event: andes_grid.GridEvent, p_ref: float, plant: str) -> dict:
    """The event's config: TG Type I's documented constants, P_e recorded, H documented."""
    sections = generate.config(generate.Event(name, "TGTypeI"), p_ref)
    what = f"{event.mw:g} MW {'on' if event.load > 0 else 'off'} at bus {event.bus}"
    sections["experiment"]["description"] = (f"ANDES Kundur two-area, gen 1 {plant}: {what}, {event.t_event:g} s; "
                                             "P_e recorded")
    sections["fitness"]["pre_step_end"] = event.t_event
    return sections


def write_events(home: Path, record: str, plant: dict, events: dict, description: str, **truth) -> None:
    """Each of ``events`` (name -> (GridEvent, the recorder's seed)) run in ANDES with
    ``record`` as generator 1's governor, recorded into ``home/<name>``."""
    from rapid_cosim.experiment import render_config

    for name, (event, seed) in events.items():
        folder = home / name
        folder.mkdir(exist_ok=True)
        run = andes_grid.run_record(record, event)
        generate.write_data(folder / "data.csv", *recorded(run, seed))
        generate.write_data(folder / "clean.csv", *recorded(run, seed, noise=False))
        (folder / "config.toml").write_text(render_config(config(name, event, float(run["pout"][0]), description)))
        facts = {"plant": plant, **truth, "event": event.__dict__, "seed": seed, "p_ref": float(run["pout"][0]),
                 "departures": {k: list(v) for k, v in run["departures"].items()}, "andes": "2.0.0"}
        (folder / "truth.json").write_text(json.dumps(facts, indent=1) + "\n")
        print(folder, f"p_ref {facts['p_ref']:.4f}, governor response {np.ptp(run['pout']):.4f} pu")


def unit_file(comment: str, name: str, events: dict, held_out: str, tail: str) -> str:
    """The unit's ``unit.toml``: its events, one held out, then ``tail`` (its structures)."""
    return (comment + f'[unit]\nname = "{name}"\nmva = 900.0\nbus = 1\nmachine_id = "1"\n\n[tests]\n'
            f"configs = [{', '.join(repr(n).replace(chr(39), chr(34)) for n in events)}]\n"
            f'holdout = ["{held_out}"]\n' + tail)
