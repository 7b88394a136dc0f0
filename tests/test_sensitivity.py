"""`fencesweep sensitivity`: the section's checks, and indices from a tiny sample."""
import textwrap

import pandas as pd
import pytest

from fencesweep.study.spec import spec as S

from fencesweep.study.spec import file as specfile
from helpers import SENSITIVITY_SPEC

SA_SPEC = SENSITIVITY_SPEC


def load(text):
    return specfile.loads(textwrap.dedent(text))


@pytest.mark.parametrize("change, words", [
    (("n: 4", "n: 6"), ["sensitivity.n = 6", "power of 2"]),
    (("mu2: {min: 0.15, max: 0.35}", "mu2: {min: 0.35, max: 0.15}"), ["min = 0.35 must be < max = 0.15"]),
    (("mu2: {min: 0.15, max: 0.35}", "drive: {min: 0, max: 1}"), ["not a numeric parameter"]),
    (("mu2: {min: 0.15, max: 0.35}", "B2: {min: 0, max: 1}"), ["also fixed"]),
    (("seed: 3", "seed: 3\n      speed: 1"), ["unknown key 'speed'"]),
    (("params: {drive: flexible, B2: 140, K2: 2075}", "params: {drive: flexible}\n    grid: {B2: [1, 2]}"),
     ["must fix its element"]),
])
def test_bad_sensitivity_sections_are_rejected(change, words):
    with pytest.raises(S.SpecError) as exc:
        load(SA_SPEC.replace(*change))
    for w in words:
        assert w in str(exc.value)


def test_indices_from_the_sample_judged_over_the_envelope(tmp_path):
    pytest.importorskip("SALib")
    from fencesweep.study.design import points as PT
    from fencesweep.study.design import sensitivity as SA

    sp = load(SA_SPEC)
    out = tmp_path / "sa.parquet"
    df = SA.run(sp, jobs=1, out=out)
    assert set(df["input"]) == {"k1", "mu2"} and set(df["output"]) == {"worst_overload", "worst_deflection_max"}
    runs = pd.read_parquet(tmp_path / "sa_runs.parquet")
    assert len(runs) == 4 * (2 + 2) * len(sp.envelope.loads)  # Saltelli: n (d + 2) points, each over the loads
    pts = pd.read_parquet(PT.points_path(tmp_path / "sa_runs.parquet"))
    worst = runs.groupby(["k1", "mu2"])["overload"].max()
    for _, p in pts.iterrows():
        assert p["worst_overload"] == worst.loc[(p["k1"], p["mu2"])]
    assert (df["output_max"] >= df["output_min"]).all()
