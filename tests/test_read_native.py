"""A table read back natively: plain pd.read_parquet gives its units and provenance in df.attrs
(pandas' PANDAS_ATTRS key beside fencesweep's own), fencesweep.read_table the same, and
fencesweep.to_xarray a Dataset over the spec's axes with each variable's unit."""
import numpy as np
import pandas as pd
import pyarrow.parquet as pq
import pytest

import fencesweep
from fencesweep.errors import UsageError
from fencesweep.study.store import table as store

xr = pytest.importorskip("xarray")

#: 2 x 3 B2 x K2 over both named cases (12 cycles of the real engine)
GRID = {"params": {"drive": "flexible"}, "grid": {"B2": [15.0, 140.0], "K2": [570.0, 1200.0, 2075.0]},
        "cases": ["small_far", "long_near"]}
#: 2 design points over an envelope of 2 x 2 corners (L; dP across) and 2 Sobol loads
ENVELOPE = {"params": {"drive": "flexible"}, "grid": {"B2": [15.0, 140.0], "K2": [2075.0]},
            "envelope": {"L": {"min": 0.2, "max": 0.7}, "dP": "across", "sobol": 2, "seed": 3}}


@pytest.fixture(scope="module")
def grid_table(tmp_path_factory):
    out = tmp_path_factory.mktemp("grid") / "grid.parquet"
    fencesweep.grid(GRID, out=out, jobs=1, progress=False)
    return out


def test_plain_pandas_reads_units_and_provenance(grid_table):
    df = pd.read_parquet(grid_table)
    assert df.attrs["units"]["B2"] == "N m s/rad" and df.attrs["units"]["peak_force"] == "N"
    meta = df.attrs["fencesweep"]
    assert meta["spec_hash"] == store.read_metadata(grid_table)["spec_hash"]
    assert meta["counts"]["scenes"] == 12 and meta["verify"]["n"] >= 1
    assert fencesweep.read_table(grid_table).attrs == df.attrs
    assert store.PANDAS_ATTRS in pq.read_schema(grid_table).metadata


def test_a_table_without_the_pandas_key_still_reads_its_attrs(grid_table, tmp_path):
    """A table written before PANDAS_ATTRS: read_table takes units and provenance from the schema."""
    t = pq.read_table(grid_table)
    old = tmp_path / "old.parquet"
    pq.write_table(t.replace_schema_metadata({k: v for k, v in t.schema.metadata.items()
                                              if k != store.PANDAS_ATTRS}), old)
    assert pd.read_parquet(old).attrs == {}
    assert fencesweep.read_table(old).attrs == pd.read_parquet(grid_table).attrs


def test_to_xarray_has_the_spec_axes_as_dimensions(grid_table):
    df = fencesweep.read_table(grid_table)
    ds = fencesweep.to_xarray(df)
    assert dict(ds.sizes) == {"case": 2, "B2": 2, "K2": 3}
    assert list(ds["case"].values) == ["small_far", "long_near"]
    assert ds["overload"].attrs["units"] == "-" and ds["deflection_max"].attrs["units"] == "rad"
    flat = df[df.case == "long_near"].pivot(index="B2", columns="K2", values="overload")
    np.testing.assert_array_equal(ds["overload"].sel(case="long_near").values, flat.to_numpy())
    assert ds["outcome"].sel(case="small_far", B2=140.0, K2=570.0).item() == \
        df.query("case == 'small_far' and B2 == 140 and K2 == 570")["outcome"].item()


def test_to_xarray_of_an_envelope_has_a_load_dimension(tmp_path):
    out = tmp_path / "env.parquet"
    fencesweep.grid(ENVELOPE, out=out, jobs=1, progress=False)
    df = pd.read_parquet(out)
    ds = fencesweep.to_xarray(df)
    n_loads = len(df) // 2
    assert dict(ds.sizes) == {"B2": 2, "K2": 1, "load": n_loads}
    assert ds["L"].dims == ("load",) and ds["dP"].dims == ("load",)
    worst = ds["overload"].fillna(0.0).max("load").sel(K2=2075.0).values
    np.testing.assert_allclose(worst, df.fillna({"overload": 0.0}).groupby("B2")["overload"].max().to_numpy())


def test_a_skipped_place_is_nan(grid_table):
    df = fencesweep.read_table(grid_table)
    part = df.drop(index=df.index[(df.B2 == 15.0) & (df.K2 == 570.0) & (df.case == "small_far")])
    part.attrs = df.attrs
    ds = fencesweep.to_xarray(part)
    assert np.isnan(ds["overload"].sel(case="small_far", B2=15.0, K2=570.0).item())
    assert np.isfinite(ds["overload"].sel(case="long_near", B2=15.0, K2=570.0).item())


def test_to_xarray_needs_the_provenance():
    with pytest.raises(UsageError, match="no fencesweep provenance"):
        fencesweep.to_xarray(pd.DataFrame({"B2": [1.0]}))


def test_a_trajectory_reads_its_attrs_with_plain_pandas(tmp_path):
    vals = fencesweep.resolve("cycle", case="small_far", B2=72.0, K2=570.0)
    r, traj = fencesweep.simulate_resolved(vals, trajectory=True)
    path = tmp_path / "traj.parquet"
    store.write_trajectory(traj, path, {"B2": 72.0, "K2": 570.0}, {"overload": r["overload"]})
    df = pd.read_parquet(path)
    assert df.attrs["params"]["B2"] == 72.0 and df.attrs["results"]["overload"] == pytest.approx(r["overload"])
    assert df.attrs == store.read_trajectory(path).attrs and df.attrs["units"]
    old = tmp_path / "old.parquet"
    t = pq.read_table(path)
    pq.write_table(t.replace_schema_metadata({k: v for k, v in t.schema.metadata.items()
                                              if k != store.PANDAS_ATTRS}), old)
    assert store.read_trajectory(old).attrs == df.attrs  # written before the key: read from the schema
