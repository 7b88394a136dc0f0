"""`fencesweep sensitivity SPEC.yaml`: Sobol indices of an element's worst overload and worst
deflection over a load envelope to the inputs the model had to assume (issue 10, item 4).

The spec's `sensitivity:` section gives each assumed input (k1, e, mu1, mu2, swing, m2, or any
numeric §12 parameter) a range {min, max}, the Saltelli base sample size n (a power of 2) and a
seed. The sample (SALib.sample.sobol, first-order and total indices) becomes a zip axis crossed
with the spec's envelope and runs as an ordinary sweep (parallel, resumable); each sample point is
judged over its loads by envelope.summarize; SALib.analyze.sobol gives S1 and ST with their 95 %
confidence half-widths. SALib is an optional dependency (pip install 'fencesweep[sensitivity]').
"""
from __future__ import annotations

from pathlib import Path
from typing import Any, Callable

import numpy as np

from fencesweep.study import envelope as E
from fencesweep.model import params as P
from fencesweep.study import spec as S

OUTPUTS = ("worst_overload", "worst_deflection_max", "worst_residual_amplitude", "min_margin")
SECTION_KEYS = ("inputs", "n", "seed", "outputs", "output")


class SensitivityError(P.ParameterError):
    """A bad sensitivity section: names the key, the value and what is allowed."""


def _bounds(inputs: Any, spec) -> dict:
    if not isinstance(inputs, dict) or len(inputs) < 2:
        raise SensitivityError(f"sensitivity.inputs = {inputs!r}: expected at least two NAME: {{min: a, max: b}}")
    bounds = {}
    for name, rng in inputs.items():
        bounds[name] = _range(name, rng, spec)
    return bounds


def _range(name: str, rng: Any, spec) -> tuple:
    where = f"sensitivity.inputs.{name}"
    if name not in P.NAMES or P.BY_NAME[name].kind == "choice":
        raise SensitivityError(f"{where}: {name!r} is not a numeric parameter of docs/model.md §12")
    if name in spec.params or name in spec.envelope.names:
        raise SensitivityError(f"{where}: {name} is also fixed in params or the envelope; remove one of them")
    if not isinstance(rng, dict) or set(rng) != {"min", "max"}:
        raise SensitivityError(f"{where} = {rng!r}: expected {{min: a, max: b}}")
    lo, hi = rng["min"], rng["max"]
    for v, k in ((lo, "min"), (hi, "max")):
        try:
            P.check_value(name, float(v))
        except (P.ParameterError, TypeError, ValueError) as exc:
            raise SensitivityError(f"{where}.{k}: {exc}") from None
    if not float(lo) < float(hi):
        raise SensitivityError(f"{where}: min = {lo!r} must be < max = {hi!r}")
    return (float(lo), float(hi))


def parse_section(raw: Any, spec) -> dict:
    if not isinstance(raw, dict):
        raise SensitivityError(f"sensitivity = {raw!r}: expected a mapping with keys {', '.join(SECTION_KEYS)}")
    bad = [k for k in raw if k not in SECTION_KEYS]
    if bad:
        raise SensitivityError(f"sensitivity: unknown key {bad[0]!r} (allowed: {', '.join(SECTION_KEYS)})")
    if spec.envelope is None:
        raise SensitivityError("sensitivity: needs an envelope: section (the loads each sample point is judged over)")
    if spec.axes[:-1] or len(spec.cases) > 1:
        raise SensitivityError("sensitivity: the spec must fix its element (no grid, zip or cases besides the "
                               "envelope): the indices are those of one element")
    bounds = _bounds(raw.get("inputs"), spec)
    n = raw.get("n", 64)
    if isinstance(n, bool) or not isinstance(n, int) or n < 2 or n & (n - 1):
        raise SensitivityError(f"sensitivity.n = {n!r}: expected a power of 2 >= 2 (the Saltelli base sample)")
    seed = raw.get("seed", 0)
    if isinstance(seed, bool) or not isinstance(seed, int) or seed < 0:
        raise SensitivityError(f"sensitivity.seed = {seed!r}: expected a whole number >= 0")
    outputs = raw.get("outputs", ["worst_overload", "worst_deflection_max"])
    if not isinstance(outputs, list) or not outputs or any(o not in OUTPUTS for o in outputs):
        raise SensitivityError(f"sensitivity.outputs = {outputs!r}: expected a list among {', '.join(OUTPUTS)}")
    output = raw.get("output", "results/sensitivity.parquet")
    if not isinstance(output, str) or not output.endswith(".parquet"):
        raise SensitivityError(f"sensitivity.output = {output!r}: expected a path ending in .parquet")
    return {"bounds": bounds, "n": n, "seed": seed, "outputs": outputs, "output": output}


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
        log: Callable[[str], None] = lambda m: None):
    """Run the sample, judge each point over the envelope, analyse; write the per-run table
    (OUT with _runs), its per-point table (_runs_points) and the indices table OUT. Returns the
    indices DataFrame."""
    import pandas as pd
    import pyarrow as pa

    from fencesweep.study import store, sweep

    cfg = spec.sensitivity
    _, analyze = _salib()
    out = Path(out or cfg["output"])
    runs, X, values = sample_spec(spec, cfg)
    table = out.with_name(out.stem + "_runs.parquet")
    sweep.run_sweep(runs, table, jobs=jobs, progress=progress, log=log, overwrite=True)
    _, pts = E.write_points(runs, table, E.spec_limits(spec))
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

