"""Compute the reference results of the validation set.

    python tests/reference/make.py                 # all scenes not yet in the CSV
    python tests/reference/make.py --force         # recompute everything
    python tests/reference/make.py --only ID[,ID]  # recompute these scenes
    python tests/reference/make.py --jobs 2 --rtol 1e-10 --method DOP853

Reads tests/reference/scenes.yaml, runs the reference model (tests/reference/model.py, scene
`cycle`) for every scene and writes tests/reference/results.csv: one row per scene with its
id, every docs/model.md §12 parameter as resolved (defaults <- case <- overrides; floats at
full precision, so that `reference.row_params` gives another implementation exactly the same
problem), the docs/model.md §11 results, per contact kind of §5 (fence, tip, rail) whether it
touched, its maximum penetration and the minimum gap (model.contact_diagnostics), the cost
(n_rhs, n_steps) and how the row was made (method, rtol, versions, hash of the
model's file and of the scene). The CSV is rewritten after every finished scene, so an
interrupted run resumes where it stopped.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import math
import os
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import scipy

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # tests/: the package `reference`

from reference import PARAM_COLS, RESULTS, SCENES, load_scenes, model, scene_hash  # noqa: E402

OUT = str(RESULTS)

RESULT_COLS = [
    "outcome", "t_exit", "peak_force", "t_peak", "peak_rail_force", "freefall_force",
    "overload", "safe", "deflection_max", "deflection_ok", "residual_deflection",
    "alpha_max", "damper_energy", "contact_energy", "t_first_contact",
    "t_last_contact", "contact_time", "n_impacts", "t_S1", "t_S2", "t_S3", "t_S4",
    "t_rail", "x_exit", "phi_exit", "max_penetration", "status", "stages",
    "t_release", "q", "n_rhs", "n_steps", "n_segments", "n_scan_events",
    "n_mode_fixes", "n_retries",
] + [f"{q}_{kind}" for kind in model.CONTACT_KINDS
     for q in ("touch", "max_pen", "min_gap")]


def _file_hash(path):
    with open(path, "rb") as fh:
        return hashlib.sha256(fh.read()).hexdigest()[:12]


def run_scene(scene, method, rtol):
    """One row of the CSV (never raises: an invalid scene gives outcome 'invalid')."""
    overrides = {k: v for k, v in scene.items() if k != "id"}
    row = {"id": scene["id"], "case": overrides.get("case", ""),
           "overrides": json.dumps(overrides, sort_keys=True)}
    try:
        p = model.resolve_params(overrides)
        row.update({k: p[k] for k in PARAM_COLS})
        res = model.simulate_reference(overrides, method=method, rtol=rtol)
        row.update({k: res.get(k, math.nan) for k in RESULT_COLS})
    except Exception as exc:  # invalid input or a bug: record it, do not stop the set
        row.update({"outcome": "invalid", "status": f"error: {exc!r}"})
    row.update({
        "ref_method": method, "ref_rtol": rtol,
        "ref_atol": "rtol*STATE_SCALE",
        "scene_hash": scene_hash(scene),
        "reference_py_hash": _file_hash(model.__file__),
        "scipy": scipy.__version__, "numpy": np.__version__,
        "python": sys.version.split()[0],
    })
    return row


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--only", action="append", default=[],
                    help="scene id(s), comma separated; may be repeated")
    ap.add_argument("--force", action="store_true", help="recompute scenes already in the CSV")
    ap.add_argument("--jobs", type=int, default=1, help="parallel workers (joblib)")
    ap.add_argument("--rtol", type=float, default=1e-10)
    ap.add_argument("--method", default="DOP853")
    ap.add_argument("--scenes", default=str(SCENES))
    ap.add_argument("--out", default=OUT)
    args = ap.parse_args(argv)

    scenes = load_scenes(args.scenes)
    only = {i for arg in args.only for i in arg.split(",") if i}
    unknown = only - {s["id"] for s in scenes}
    if unknown:
        ap.error(f"unknown scene id(s): {sorted(unknown)}")

    old = pd.read_csv(args.out) if os.path.exists(args.out) else pd.DataFrame()
    done = {}
    if len(old):
        for rec in old.to_dict("records"):
            done[rec["id"]] = rec
    todo = []
    for s in scenes:
        sid = s["id"]
        if only:
            if sid in only:
                todo.append(s)
        elif args.force or sid not in done or done[sid].get("scene_hash") != scene_hash(s):
            todo.append(s)
    print(f"{len(scenes)} scenes, {len(todo)} to compute "
          f"(method {args.method}, rtol {args.rtol:g}, jobs {args.jobs})", flush=True)

    order = [s["id"] for s in scenes]

    def write():
        rows = [done[i] for i in order if i in done]
        cols = ["id", "case", "overrides"] + PARAM_COLS + RESULT_COLS
        df = pd.DataFrame(rows)
        df = df[[c for c in cols if c in df.columns] +
                [c for c in df.columns if c not in cols]]
        tmp = args.out + ".tmp"
        df.to_csv(tmp, index=False)        # floats at full (round-trip) precision
        os.replace(tmp, args.out)

    def report(i, row):
        done[row["id"]] = row
        write()
        print(f"[{i:3d}/{len(todo)}] {row['id']:34s} {str(row.get('outcome')):8s} "
              f"t_exit={row.get('t_exit', math.nan):.5f} "
              f"peak={row.get('peak_force', math.nan):10.3f} N "
              f"defl={row.get('deflection_max', math.nan):.5f} "
              f"n_rhs={row.get('n_rhs', 0)} "
              f"{'' if row.get('status') == 'ok' else row.get('status')}", flush=True)

    if args.jobs > 1 and len(todo) > 1:
        from joblib import Parallel, delayed
        gen = Parallel(n_jobs=args.jobs, return_as="generator_unordered")(
            delayed(run_scene)(s, args.method, args.rtol) for s in todo)
        for i, row in enumerate(gen, 1):
            report(i, row)
    else:
        for i, s in enumerate(todo, 1):
            report(i, run_scene(s, args.method, args.rtol))
    if not todo:
        write()
    print(f"done -> {os.path.relpath(args.out)}")


if __name__ == "__main__":
    main()
