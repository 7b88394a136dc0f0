"""The independent reference: the sorting-cycle model written a second time, apart from the
engine, and its results on the validation scenes, from which the tests and the benchmarks
measure the engine's error.

    model.py        the model (docs/model.md §1-§12) as a plain NumPy right-hand side, integrated
                    by SciPy's solve_ivp with event restarts; it imports nothing from fencesweep
    scenes.yaml     the validation scenes: an id and parameter overrides each
    results.csv     the reference's results of every scene (DOP853 at rtol 1e-10), with every
                    parameter as resolved
    make.py         computes results.csv from scenes.yaml: `python tests/reference/make.py`
    find_grazes.py  finds the values of the grazing scenes, with the reference alone
    compare.py      judges an engine's results against a row: the errors, floors and bound of
                    tests/test_validation.py (the one module here that imports fencesweep: its
                    agreement metric, fencesweep/study/sweep/accuracy.py)

This module reads the scenes and the CSV. The tests import the package as `reference`
(pyproject.toml's pytest pythonpath is tests/); a benchmark puts tests/ on sys.path itself.
"""
from __future__ import annotations

import hashlib
import json
from pathlib import Path

import yaml

from . import model

HERE = Path(__file__).resolve().parent
#: the validation scenes (ids and overrides)
SCENES = HERE / "scenes.yaml"
#: the reference's results of every scene, one row each
RESULTS = HERE / "results.csv"
#: the columns of docs/model.md §12 parameters in results.csv, in the reference's order
PARAM_COLS = list(model.DEFAULTS)


def rows(path: Path = RESULTS) -> list[dict]:
    """The rows of results.csv, as dicts, in the order of the scenes."""
    import pandas as pd

    return pd.read_csv(path).to_dict("records")


def row_params(row) -> dict:
    """The fully resolved docs/model.md §12 parameters of one CSV row, as keyword arguments.

    Every §12 value the reference ran with (defaults, case and overrides already applied, I2
    and t_max explicit), so that another implementation given these solves exactly the
    reference's problem. k_lin is passed only under the linear law (under the Hertz law it is
    unused). `row` is a mapping (a dict or a pandas Series).
    """
    out = {}
    for k in PARAM_COLS:
        val = row[k]
        if k in model.STRING_PARAMS:
            out[k] = str(val)
        elif k == "k_lin" and row["contact_law"] != "linear":
            continue
        else:
            out[k] = float(val)
    return out


def load_scenes(path: Path = SCENES) -> list[dict]:
    """The scenes of scenes.yaml (ids unique)."""
    with open(path) as fh:
        scenes = yaml.safe_load(fh)["scenes"]
    ids = [s["id"] for s in scenes]
    dup = {i for i in ids if ids.count(i) > 1}
    if dup:
        raise ValueError(f"duplicate scene ids: {sorted(dup)}")
    return scenes


def scene_hash(scene: dict) -> str:
    """Hash of a scene's overrides (everything but its id), as the CSV records it."""
    overrides = {k: v for k, v in scene.items() if k != "id"}
    return hashlib.sha256(json.dumps(overrides, sort_keys=True).encode()).hexdigest()[:12]
