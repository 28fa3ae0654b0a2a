"""Experiments made in code: from arrays or a pandas DataFrame, checked exactly as a
config file is (they are rendered to one and read back by the loader)."""

from __future__ import annotations

from pathlib import Path
from typing import Any, Mapping

import numpy as np

from ..data import MeasuredData
from ..errors import DataError
from .config import parse_experiment
from .definition import CONFIG_NAME, IN_MEMORY, Experiment
from .toml_writer import render_config


def experiment_from_arrays(name: str, model: str, time, outputs: Mapping[str, Any], *,
                           fixed: Mapping[str, float] | None = None,
                           estimate: Mapping[str, Any] | None = None, description: str = "",
                           fitness: Mapping[str, Any] | None = None,
                           simulation: Mapping[str, Any] | None = None) -> Experiment:
    """An experiment built in code: ``outputs`` maps each model output to its measured
    values on ``time`` (NaN where missing). ``estimate`` maps parameters to
    ``(min, max)`` or to a table as in a config (``{"min": 0.02, "max": 0.12,
    "label": "R"}``); ``fitness`` and ``simulation`` take the keys of those config
    sections (``{"offset": True, "noise": "pre-step", "pre_step_end": 10.0}``).

    It is checked exactly as a config file is, and carries the config text it
    stands for, so archives of its runs re-run from the archive alone.
    """
    data = MeasuredData.from_arrays(time, {out: np.asarray(v, dtype=float) for out, v in outputs.items()},
                                    source=f"{name} (arrays)")
    specs = {p: ({"min": float(v[0]), "max": float(v[1])} if isinstance(v, (tuple, list)) else dict(v))
             for p, v in (estimate or {}).items()}
    sections: dict[str, Any] = {
        "experiment": {"name": name, "model": model, "description": description},
        "data": {"file": IN_MEMORY, "time": "time", "outputs": {out: out for out in outputs}},
        "fixed": dict(fixed or {}), "estimate": specs, "fitness": dict(fitness or {}),
        "simulation": dict(simulation or {})}
    text = render_config({k: v for k, v in sections.items() if v or k in ("experiment", "data")})
    return parse_experiment(text, Path(IN_MEMORY) / name / CONFIG_NAME, data=data)


def experiment_from_frame(name: str, model: str, frame, *, time: str = "time",
               outputs: Mapping[str, str] | None = None, **kwargs) -> Experiment:
    """As :func:`experiment_from_arrays`, from a pandas DataFrame: ``time`` names its time column
    and ``outputs`` maps model outputs to columns (default: every other column, by
    its own name)."""
    if time not in frame.columns:
        raise DataError(f"the frame has no time column {time!r}; columns: {', '.join(map(str, frame.columns))}",
                        name)
    outputs = dict(outputs) if outputs is not None else {str(c): str(c) for c in frame.columns if c != time}
    missing = [c for c in outputs.values() if c not in frame.columns]
    if missing:
        raise DataError(f"the frame has no column(s) {', '.join(missing)}; columns: "
                        f"{', '.join(map(str, frame.columns))}", name)
    return experiment_from_arrays(name, model, frame[time].to_numpy(dtype=float),
                           {out: frame[col].to_numpy(dtype=float) for out, col in outputs.items()}, **kwargs)
