"""A sweep table as an xarray.Dataset whose dimensions are its spec's axes (fencesweep.to_xarray).

The table is flat: one row per scene. Its provenance (df.attrs["fencesweep"]["spec"]) names the
axes: a grid axis of one parameter is a dimension of that name; a zip group is one dimension with
a coordinate per zipped parameter (the envelope's is `load`, a sensitivity sample's `sample`);
a spec with several cases has a `case` dimension; a stream table has `cycle`. Each row's place on
every dimension is found by matching its values against the axis's (a scene the spec skipped, or
an element an adaptive run inferred, is NaN in the Dataset). Every other column is a variable over
those dimensions, its unit in its attrs["units"].
"""
from __future__ import annotations

import numpy as np

from fencesweep.errors import UsageError

#: the dimension of a zip group, by where the spec put it (others: the group's name)
ZIP_DIMS = {"envelope": "load", "sensitivity": "sample"}
#: relative closeness at which a row's value is the axis's (a derived column such as Psi is
#: recomputed from the parameters, so it may differ from the spec's value in its last digits)
MATCH_RTOL = 1e-9


def _xarray():
    try:
        import xarray
    except ImportError:
        raise UsageError("fencesweep.to_xarray needs xarray: pip install 'fencesweep[xarray]' "
                         "(or pip install xarray)") from None
    return xarray


def _positions(column: np.ndarray, values: list) -> np.ndarray:
    """The index into `values` of each entry of `column` (-1 where none is the same)."""
    if column.dtype.kind in "OUS":
        lookup = {v: i for i, v in enumerate(values)}
        return np.array([lookup.get(v, -1) for v in column], dtype=np.int64)
    vals = np.asarray(values, dtype=float)
    order = np.argsort(vals, kind="stable")
    col = column.astype(float)
    at = np.clip(np.searchsorted(vals[order], col), 0, len(vals) - 1)
    near = np.stack([order[np.maximum(at - 1, 0)], order[at]])
    best = near[np.argmin(np.abs(vals[near] - col), axis=0), np.arange(len(col))]
    ok = np.isclose(vals[best], col, rtol=MATCH_RTOL, atol=0.0)
    return np.where(ok, best, -1)


def _zip_index(df, names: list, values: list) -> np.ndarray:
    """Each row's entry of a zip group (-1 where its values are none of the group's): each name's
    column coded by its distinct values, the codes of a row looked up among the entries'."""
    distinct = [sorted({row[j] for row in values}, key=_key) for j in range(len(names))]
    sizes = tuple(len(d) for d in distinct)
    rows = np.stack([_positions(df[n].to_numpy(), d) for n, d in zip(names, distinct)])
    entries = np.array([[d.index(row[j]) for j, d in enumerate(distinct)] for row in values]).T
    found = (rows >= 0).all(axis=0)
    row_key = np.ravel_multi_index(np.where(found, rows, 0), sizes)
    entry_key = np.ravel_multi_index(entries, sizes)
    order = np.argsort(entry_key)
    at = np.clip(np.searchsorted(entry_key[order], row_key), 0, len(order) - 1)
    hit = found & (entry_key[order][at] == row_key)
    return np.where(hit, order[at], -1)


def _key(v):
    return (0, float(v), "") if isinstance(v, (int, float)) else (1, 0.0, str(v))


def _case_labels(cases: list) -> list:
    """A label per case: its name, else its parameters ("B2=72, K2=570")."""
    return [c["case"] or ", ".join(f"{k}={v}" for k, v in c["params"].items()) or f"case {i}"
            for i, c in enumerate(cases)]


def _case_index(df, cases: list) -> np.ndarray:
    """Each row's case (-1: none): by the `case` column when every case has a name, else by the
    parameters each case sets."""
    if all(c["case"] for c in cases):
        return _positions(df["case"].to_numpy(dtype=object), [c["case"] for c in cases])
    idx = np.full(len(df), -1, dtype=np.int64)
    for i, c in enumerate(cases):
        hit = np.ones(len(df), dtype=bool)
        for k, v in c["params"].items():
            hit &= _positions(df[k].to_numpy(), [v]) == 0
        idx[hit & (idx < 0)] = i
    return idx


def _dims(df, spec: dict) -> list:
    """[(dimension, index of each row, {coordinate: values})] of the spec's axes, outermost first."""
    out = []
    cases = spec.get("cases") or []
    if len(cases) > 1:
        out.append(("case", _case_index(df, cases), {"case": _case_labels(cases)}))
    for axis in spec["axes"]:
        names, values = axis["names"], [tuple(v) for v in axis["values"]]
        if len(names) == 1:
            out.append((names[0], _positions(df[names[0]].to_numpy(), [v[0] for v in values]),
                        {names[0]: [v[0] for v in values]}))
        else:
            dim = ZIP_DIMS.get(axis["from"], axis["from"].split(".")[-1])
            coords = {n: [v[j] for v in values] for j, n in enumerate(names)}
            out.append((dim, _zip_index(df, names, values), coords))
    if "cycle" in df.columns:
        cyc = np.unique(df["cycle"].to_numpy())
        out.append(("cycle", _positions(df["cycle"].to_numpy(), list(cyc)), {"cycle": list(cyc)}))
    return out


def to_xarray(df):
    """The sweep table `df` (fencesweep.read_table or pd.read_parquet of a fencesweep table) as an
    xarray.Dataset over its spec's axes (module docstring); units in each variable's attrs."""
    xr = _xarray()
    prov = df.attrs.get("fencesweep") or {}
    if "spec" not in prov:
        raise UsageError("to_xarray: the DataFrame has no fencesweep provenance (df.attrs['fencesweep']['spec']); "
                         "read the table with fencesweep.read_table(path) or pd.read_parquet(path)")
    dims = _dims(df, prov["spec"])
    missing = [d for d, idx, _ in dims if (idx < 0).any()]
    if missing:
        raise UsageError(f"to_xarray: some rows are on no value of the spec's {', '.join(missing)} axis")
    shape = tuple(len(next(iter(c.values()))) for _, _, c in dims)
    flat = np.ravel_multi_index(tuple(idx for _, idx, _ in dims), shape)
    if len(np.unique(flat)) != len(flat):
        raise UsageError("to_xarray: two rows share one place on the spec's axes")
    coord_cols = {n for _, _, c in dims for n in c}
    units = df.attrs.get("units") or {}
    data = {}
    for col in df.columns:
        if col in coord_cols:
            continue
        data[col] = (tuple(d for d, _, _ in dims), _filled(df[col].to_numpy(), flat, shape),
                     {"units": units.get(col, "")})
    coords = {n: (d, np.asarray(v)) for d, _, c in dims for n, v in c.items()}
    return xr.Dataset(data, coords=coords, attrs={"fencesweep": str(prov.get("spec_path") or "")})


def _filled(values: np.ndarray, flat: np.ndarray, shape: tuple) -> np.ndarray:
    """`values` placed at `flat` in an array of `shape`, NaN (None for text) elsewhere."""
    kind = values.dtype.kind
    if len(flat) == int(np.prod(shape)):  # every place has its row: the column's own type
        out = np.empty(len(flat), dtype=values.dtype)
        out[flat] = values
        return out.reshape(shape)
    if kind in "fc":
        out = np.full(int(np.prod(shape)), np.nan, dtype=values.dtype)
    elif kind in "iub":
        out = np.full(int(np.prod(shape)), np.nan)
    else:
        out = np.full(int(np.prod(shape)), None, dtype=object)
    out[flat] = values
    return out.reshape(shape)
