"""`fencesweep sensitivity SPEC.yaml`: Sobol indices of an element's worst overload and worst
deflection over a load envelope to the inputs the model had to assume.

The spec's `sensitivity:` section gives each assumed input (k1, e, mu1, mu2, swing, m2, or any
numeric §12 parameter) a range {min, max}, the Saltelli base sample size n (a power of 2) and a
seed. The sample (SALib.sample.sobol, first-order and total indices) becomes a zip axis crossed
with the spec's envelope and runs as an ordinary sweep (parallel, resumable); each sample point is
judged over its loads by envelope.summarize; SALib.analyze.sobol gives S1 and ST with their 95 %
confidence half-widths. SALib is an optional dependency (pip install 'fencesweep[sensitivity]').
"""
from __future__ import annotations

from pathlib import Path
from typing import Callable

import numpy as np

from fencesweep.study.design import judge as J
from fencesweep.study.design import points as PT
from fencesweep.study.spec import envelope as E
from fencesweep.study.spec import spec as S


def _salib():
    try:
        from SALib.analyze import sobol as analyze
        from SALib.sample import sobol as sample
    except ImportError:
        from fencesweep.errors import UsageError

        raise UsageError("fencesweep sensitivity needs SALib: pip install 'fencesweep[sensitivity]' "
                         "(or pip install SALib)") from None
    return sample, analyze


def problem(cfg: dict) -> dict:
    return {"num_vars": len(cfg["bounds"]), "names": list(cfg["bounds"]), "bounds": list(cfg["bounds"].values())}


def sample_spec(spec, cfg: dict):
    """The spec of the runs: the Saltelli sample as a zip axis, crossed with the envelope."""
    sample, _ = _salib()
    X = sample.sample(problem(cfg), cfg["n"], calc_second_order=False, seed=cfg["seed"])
    names = tuple(cfg["bounds"])
    values = tuple(tuple(E._round(float(v)) for v in row) for row in X)
    axes = [S.Axis(names, values, "sensitivity"), *spec.axes]
    runs = S.Spec(scene=spec.scene, case=spec.case, params=dict(spec.params), axes=axes, cases=spec.cases,
                  invalid=spec.invalid, chunk_size=spec.chunk_size, description=spec.description,
                  source=spec.source, path=spec.path, envelope=spec.envelope)
    return runs, X, values


def run(spec, jobs: int | None = None, progress: bool = False, out: str | Path | None = None,
        log: Callable[[str], None] = lambda m: None, backend: str = "loky", scheduler: str | None = None):
    """Run the sample (a sweep: on `jobs` local processes, or with backend "dask" on the cluster at
    `scheduler`), judge each point over the envelope, analyse; write the per-run table (OUT with
    _runs), its per-point table (_runs_points) and the indices table OUT. Returns the indices
    DataFrame."""
    import pandas as pd
    import pyarrow as pa

    from fencesweep.study.store import table as store
    from fencesweep.study.sweep import pipeline as sweep

    cfg = spec.sensitivity
    _, analyze = _salib()
    out = Path(out or cfg["output"])
    runs, X, values = sample_spec(spec, cfg)
    table = out.with_name(out.stem + "_runs.parquet")
    sweep.run_sweep(runs, table, jobs=jobs, progress=progress, log=log, overwrite=True, backend=backend,
                    scheduler=scheduler)
    _, pts = PT.write_points(runs, table, J.spec_limits(spec))
    names = list(cfg["bounds"])
    key = pd.DataFrame(values, columns=names)
    Y = key.merge(pts, on=names, how="left")
    rows = []
    for o in cfg["outputs"]:
        y = Y[o].to_numpy(dtype=float)
        si = analyze.analyze(problem(cfg), y, calc_second_order=False, seed=cfg["seed"], print_to_console=False)
        for k, name in enumerate(names):
            lo, hi = cfg["bounds"][name]
            rows.append({"output": o, "input": name, "min": lo, "max": hi, "S1": float(si["S1"][k]),
                         "S1_conf": float(si["S1_conf"][k]), "ST": float(si["ST"][k]), "ST_conf": float(si["ST_conf"][k]),
                         "output_min": float(np.nanmin(y)), "output_max": float(np.nanmax(y)),
                         "output_mean": float(np.nanmean(y))})
    df = pd.DataFrame(rows)
    meta = {"spec_hash": spec.hash, "spec_path": spec.path, "n": cfg["n"], "seed": cfg["seed"],
            "n_points": len(X), "n_loads": len(spec.envelope.loads), "cycles": len(X) * len(spec.envelope.loads),
            "fixed": {k: v for k, v in spec.params.items()}, "versions": store.versions()}
    t = pa.Table.from_pandas(df, preserve_index=False)
    store.write_table_atomic(t.replace_schema_metadata({**(t.schema.metadata or {}), **store._meta_bytes(meta)}), out)
    return df


def summary_lines(df) -> list:
    out = ["| output | input | range | S1 | ST |", "|---|---|---|---|---|"]
    for _, r in df.sort_values(["output", "ST"], ascending=[True, False]).iterrows():
        out.append(f"| {r['output']} | {r['input']} | {r['min']:g} - {r['max']:g} | {r['S1']:.3f} +- {r['S1_conf']:.3f} "
                   f"| {r['ST']:.3f} +- {r['ST_conf']:.3f} |")
    return out

