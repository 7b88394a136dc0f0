"""The risk study's tables: OUT (one row per element and operating point) and, with
risk.samples: true, OUT_samples.parquet (one row per cycle run). Units per column and the
provenance in df.attrs, as every table of fencesweep (store/table.py)."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from fencesweep.model import params as P
from fencesweep.study.risk import sequential as SQ
from fencesweep.study.spec import population as PO
from fencesweep.study.spec.risk import RiskSpec
from fencesweep.study.store import table as store

EVENT_DOC = {"overload": "overload > risk.limits.overload (the fence hits the parcel harder than the permitted "
                         "drop test, docs/model.md §7)",
             "not_scraped": "outcome != scraped (the parcel is not sorted: escaped, jammed or a failed run; §9)",
             "deflection": "deflection_max > the deflection limit (dalpha_perm unless risk.limits says; §11)",
             "residual": "residual_amplitude > risk.limits.residual_amplitude (the fence is not home; §11)",
             "any": "any of the four"}
INTERVAL = ("Clopper-Pearson (exact binomial) at level 1 - alpha_k at look k, the alpha_k of the plan summing to "
            "alpha = 1 - confidence: by the union bound the intervals of every look hold together with probability "
            ">= confidence, so the one at the data-chosen stop does too; valid for i.i.d. pseudo-random draws")


def samples_path(out) -> Path:
    out = Path(out)
    return out.with_name(out.stem + "_samples.parquet")


def _columns(sp: RiskSpec, state: SQ.State) -> tuple:
    """{column: values}, {column: (unit, doc)} of the per-unit table."""
    units = sp.units
    cols, meta = {}, {}
    for name in sp.element_names:
        cols[name] = [sp.elements[e].get(name, np.nan) for e, _ in units]
        meta[name] = (P.BY_NAME[name].unit, f"the element's {name} (docs/model.md §12)")
    cols["label"] = [sp.labels[e] for e, _ in units]
    meta["label"] = ("-", "the element's name in the spec's compare: (null: an element of the grid or list)")
    for name in ("t_c", "v", "drive"):
        cols[name] = [P.resolve("cycle", **sp.inputs(u))[name] for u in range(len(units))]
        meta[name] = (P.BY_NAME[name].unit, f"{name} of the operating point (docs/model.md §12)")
    cols["n"] = state.n
    meta["n"] = ("-", "parcels sampled (cycles run) for this element and operating point")
    cols["looks"] = state.looks
    meta["looks"] = ("-", "looks taken on the plan")
    cols["level"] = 1 - state.alpha
    meta["level"] = ("-", "the level of the intervals: 1 - alpha_k of the look where the unit stopped")
    cols["decision"] = state.decision.astype(str)
    meta["decision"] = ("-", "below / above: the P(any) interval lies wholly below / above p_max; undecided: the cap "
                        "was reached first")
    for ev, (p, lo, hi) in SQ.intervals(state).items():
        j = SQ.ALL.index(ev)
        cols[f"n_{ev}"] = state.counts[:, j]
        meta[f"n_{ev}"] = ("-", f"parcels sampled with {EVENT_DOC[ev]}")
        for suffix, v, what in (("", p, "the share of the sample"), ("_lo", lo, "its interval's lower end"),
                                ("_hi", hi, "its interval's upper end")):
            cols[f"p_{ev}{suffix}"] = v
            meta[f"p_{ev}{suffix}"] = ("-", f"P({EVENT_DOC[ev]}): {what}")
        cols[f"in_10000_{ev}"] = p * 1e4
        meta[f"in_10000_{ev}"] = ("parcels in 10,000", f"p_{ev} x 10,000: the parcels in 10,000 with {EVENT_DOC[ev]}")
    return cols, meta


def _arrow(cols: dict, meta: dict):
    import pyarrow as pa

    fields, arrays = [], []
    for name, vals in cols.items():
        arr = pa.array(list(vals) if not isinstance(vals, np.ndarray) else vals)
        unit, doc = meta[name]
        fields.append(pa.field(name, arr.type, metadata={b"unit": unit.encode(), b"doc": doc.encode(),
                                                          b"role": b"result"}))
        arrays.append(arr)
    return pa.Table.from_arrays(arrays, schema=pa.schema(fields))


def _provenance(sp: RiskSpec, state: SQ.State, parcels: dict, record: dict) -> dict:
    sizes, alphas = sp.plan()
    pop = sp.population
    return {"spec": sp.normalized(), "spec_hash": sp.hash, "spec_path": sp.path, "spec_source": sp.source,
            "versions": store.versions(),
            "risk": {"p_max": sp.p_max, "confidence": sp.confidence, "schedule": sizes, "looks": len(sizes),
                     "alpha_per_look": alphas, "interval": INTERVAL,
                     "samples": "plain pseudo-random (numpy PCG64, seeded), the same parcels for every unit",
                     "limits": sp.normalized()["risk"]["limits"]},
            "population": pop.definition() | {"drawn": parcels["drawn"], "too_large_left_out_of_draws":
                                              parcels["too_large"], "file_rows_left_out": pop.left_out[:50],
                                              "n_file_rows_left_out": len(pop.left_out)},
            "counts": {"units": len(sp.units), "elements": len(sp.elements), "operating_points": len(sp.operating),
                       "cycles": state.cycles, "cycles_at_cap": len(sp.units) * sp.cap}}


def write(sp: RiskSpec, out: Path, state: SQ.State, parcels: dict, samples, record: dict) -> dict:
    """Write OUT (and OUT_samples.parquet); the table's summary for the run's record."""
    cols, meta = _columns(sp, state)
    table = _arrow(cols, meta)
    prov = _provenance(sp, state, parcels, record)
    units = {f.name: f.metadata[b"unit"].decode() for f in table.schema}
    table = table.replace_schema_metadata(store._meta_bytes(prov))
    store.write_table_atomic(table, out, attrs={"units": units, "fencesweep": prov})  # nothing of the run's time or jobs
    spath = None
    if sp.samples and samples is not None:
        spath = str(samples_path(out))
        _write_samples(sp, samples, parcels, spath, prov)
    d = np.asarray(cols["decision"])
    return {"out": str(out), "samples_path": spath, "units": len(sp.units),
            "below": int((d == SQ.BELOW).sum()), "above": int((d == SQ.ABOVE).sum()),
            "undecided": int((d == SQ.UNDECIDED).sum())}


def _write_samples(sp: RiskSpec, df, parcels: dict, path: str, prov: dict) -> None:
    import pyarrow as pa

    df = df.sort_values(["unit", "sample"], kind="stable").reset_index(drop=True)
    units = sp.units
    e = np.array([units[u][0] for u in df["unit"]])
    for name in sp.element_names:
        df[name] = [sp.elements[k].get(name, np.nan) for k in e]
    for c in PO.SIZES + PO.PLACES:
        df[c] = parcels[c][df["sample"].to_numpy()]
    unit_of = {c: P.BY_NAME[c].unit for c in df.columns if c in P.BY_NAME}
    table = pa.Table.from_pandas(df, preserve_index=False)
    table = table.replace_schema_metadata(store._meta_bytes(prov))
    store.write_table_atomic(table, path, attrs={"units": unit_of, "fencesweep": prov})
