"""Adaptive maps: the points table T_points and the run's record.

T_points (OUT_points.parquet) has one row per element of the full grid, in the order of the
full grid's scenes: the columns that name it (adaptive_maps.Layout.columns), then the columns
of the full run's per-design-point table (envelope.summarize) and

* `sampled`: the element was simulated. Its columns are the full run's, judged over the loads
  it ran: every load (n_loads = the envelope's), up to the first that broke a constraint
  (infeasible; its margins and worst values are then over those loads only: upper bounds of
  the margins, and `binding` is a constraint that is broken, not necessarily the most broken),
  or up to the loads predicted safe (feasible; `n_predicted` of them, adaptive/loads.py).
* not sampled: inferred (adaptive/refine.py): the verdict and binding constraint of the cell or face
  it lies in, min_margin and the margins interpolated multilinearly between its corners;
  n_loads 0, the worst values and counts empty (null).

A grid with cases names the verdict `ok` (scraped, overload <= 1, deflection within the limit)
instead of `feasible`. full_points judges a full grid's table the same way, for comparisons.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from fencesweep.study.adaptive import refine as A
from fencesweep.study.adaptive.maps import Layout
from fencesweep.study.design import judge as J
from fencesweep.study.design import points as PT

COUNTS = ("n_escaped", "worst_overload_load", "worst_deflection_max_load", "worst_residual_amplitude_load")


def verdict_name(lay: Layout) -> str:
    return "feasible" if lay.mode == "envelope" else "ok"


def record(lay: Layout, refiner: A.Refiner, ev) -> dict:
    """The run's record (T's and T_points' metadata `fencesweep.adaptive`): plain JSON, no times."""
    status = refiner.status
    simulated = int((status == A.SAMPLED).sum())
    return {
        "mode": lay.mode, "verdict": verdict_name(lay), "cycles": int(ev.cycles), "full_grid_cycles": int(lay.n_full),
        "share": round(ev.cycles / lay.n_full, 6), "design_points": int(lay.grid.n_elements),
        "maps": int(lay.grid.n_maps), "map_shape": list(lay.grid.shape), "loads": int(lay.n_loads),
        "simulated": simulated, "inferred": int(lay.grid.n_elements - simulated),
        "stopped_at_a_broken_constraint": int(ev.stats["stopped"]),
        "feasible_with_predicted_loads": int(ev.stats["predicted"]), "loads_predicted": int(ev.stats["loads_predicted"]),
        "levels": [{"step": h, "simulated": a, "inferred_on_faces": b} for h, a, b in refiner.levels],
        "rule": refiner.rule.as_dict(), "load_rule": ev.rule.as_dict(), "limits": lay.limits.as_dict(),
    }


def table(lay: Layout, refiner: A.Refiner, ev):
    """T_points as a DataFrame (module docstring)."""
    import pandas as pd

    status, feas, bind, marg, mm = refiner.result()
    n = lay.grid.n_elements
    df = pd.DataFrame(lay.columns())
    judged = J.summarize(pd.concat(ev.frames, ignore_index=True), ["_element"], lay.limits)
    at = judged["_element"].to_numpy()
    for c in judged.columns:
        if c in ("_element", "feasible", "binding", "min_margin", *J.MARGINS):
            continue
        if c == "n_loads":
            col = np.zeros(n, dtype=np.int64)
        elif c in COUNTS:
            col = pd.array([pd.NA] * n, dtype="Int64")
        else:
            col = np.full(n, np.nan)
        col[at] = judged[c].to_numpy()
        df[c] = col
    for j, c in enumerate(J.MARGINS):
        df[c] = marg[:, j]
    df["min_margin"] = mm
    df["binding"] = [J.MARGINS[b].removeprefix("margin_") for b in bind]
    df[verdict_name(lay)] = feas
    df["sampled"] = status == A.SAMPLED
    predicted = np.zeros(n, dtype=np.int64)
    predicted[list(ev.predicted)] = list(ev.predicted.values())
    df["n_predicted"] = predicted
    return df


def write(lay: Layout, refiner: A.Refiner, ev, out: Path, rec: dict) -> tuple:
    """Write T_points beside T (envelope.points_path) with its provenance; (path, summary)."""
    import pyarrow as pa

    from fencesweep.study.store import table as store

    pts = table(lay, refiner, ev)
    path = PT.points_path(out)
    spec = lay.spec
    meta = {"spec_hash": spec.hash, "spec_path": spec.path, "limits": lay.limits.as_dict(), "per_load_table": str(out),
            "versions": store.versions(), "adaptive": rec}
    if spec.envelope is not None:
        meta["envelope"] = spec.envelope.definition()
    t = pa.Table.from_pandas(pts, preserve_index=False)
    t = t.replace_schema_metadata({**(t.schema.metadata or {}), **store._meta_bytes(meta)})
    store.write_table_atomic(t, path)
    return path, summary(lay, pts, path)


def summary(lay: Layout, pts, path: Path) -> dict:
    """What the CLI prints of T_points: its size, the verdicts, the best simulated element."""
    v = verdict_name(lay)
    full = pts[pts["sampled"] & (pts["n_loads"] + pts["n_predicted"] == lay.n_loads)]
    best = full.loc[full["min_margin"].idxmax()] if len(full) else pts.loc[pts["min_margin"].idxmax()]
    names = [c for c in pts.columns if c not in _VALUE_COLUMNS]
    return {"path": str(path), "design_points": len(pts), "loads": lay.n_loads, "feasible": int(pts[v].sum()),
            "sampled": int(pts["sampled"].sum()), "min_margin": float(best["min_margin"]),
            "binding": str(best["binding"]), "best": {c: _plain(best[c]) for c in names}, "verdict": v}


_VALUE_COLUMNS = {"n_loads", "share_scraped", "n_escaped", "worst_overload", "worst_overload_load",
                  "worst_deflection_max", "worst_deflection_max_load", "worst_residual_amplitude",
                  "worst_residual_amplitude_load", *J.MARGINS, "min_margin", "binding", "feasible", "ok", "sampled",
                  "n_predicted"}


def _plain(x):
    return x.item() if hasattr(x, "item") else x


def full_points(lay: Layout, df):
    """The full grid's table `df` (every scene of lay.spec) judged per element as T_points judges
    the simulated ones: [element order] with the verdict, min_margin, binding and margins."""
    if len(df) != lay.spec.n_scenes:
        raise ValueError(f"the full grid has {lay.spec.n_scenes} scenes; this table has {len(df)} rows")
    frame = df[["outcome", "overload", "deflection_max", "residual_amplitude", "dalpha_perm"]].reset_index(drop=True)
    frame["_element"], frame["load"] = lay.element_of(np.arange(len(df)))
    pts = J.summarize(frame, ["_element"], lay.limits).set_index("_element").sort_index()
    return pts.rename(columns={"feasible": verdict_name(lay)})
