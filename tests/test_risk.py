"""`fencesweep risk`: the intervals' coverage and the sequential stop on a Bernoulli stand-in of
known probabilities (study/risk/sequential.py is pure), the estimate against a brute-force count
of the same parcels through `grid`, the draws' reproducibility, resume after an interrupt, and
bad input (one line naming the row or the name, exit code 2, nothing written)."""
from __future__ import annotations

import copy

import numpy as np
import pytest

import fencesweep
from fencesweep.cli import main
from fencesweep.study.risk import sequential as SQ
from fencesweep.study.spec import population as PO
from fencesweep.study.spec import risk as RS

BASE = {
    "params": {"drive": "flexible"},
    "elements": [{"B2": 231.0, "K2": 925.0}, {"B2": 15.0, "K2": 2075.0}],
    "operating": {"t_c": 1.36, "v": 2.0},
    "population": {"L": {"dist": "lognorm", "s": 0.35, "scale": 0.32, "min": 0.2, "max": 0.7},
                   "A": {"min": 0.1, "max": 0.2},
                   "m1": {"dist": "lognorm", "s": 0.3, "scale": 8.0, "min": 5, "max": 15},
                   "R_s": {"min": -0.4, "max": 0.6}, "seed": 7},
    "risk": {"p_max": 0.05, "first": 12, "cap": 12, "samples": True},
}


def spec(**changes) -> dict:
    d = copy.deepcopy(BASE)
    for key, value in changes.items():
        d[key] = value
    return d


# ------------------------------------------------------------------ the stand-in engine
def bernoulli(p: np.ndarray, seed: int):
    """evaluate(units, start, stop) of independent events of probabilities p [units, 4]: sample
    i of unit u is the same whatever the rounds (its uniforms are a prefix of one stream)."""
    def evaluate(units, start, stop):
        out = np.empty((len(units), stop - start, len(SQ.EVENTS)), dtype=bool)
        for j, u in enumerate(units):
            u_all = np.random.default_rng([seed, int(u)]).random((stop, len(SQ.EVENTS)))
            out[j] = u_all[start:stop] < p[u]
        return out
    return evaluate


def p_any(p: np.ndarray) -> np.ndarray:
    return 1 - np.prod(1 - p, axis=1)


@pytest.mark.parametrize("scale", [0.6, 1.0, 2.0])
def test_interval_covers_the_true_probability_under_repeated_looks(scale):
    """200 seeded repetitions (independent units) of a case of known P(any): at p_max (about all
    of them run to the cap), below and above it (they stop at looks the data choose): the interval
    at the stop covers the truth in >= 93 % of them, for each event and any."""
    p = np.tile(np.array([0.004, 0.003, 0.002, 0.001]) * scale, (200, 1))
    st = SQ.run_rounds(200, bernoulli(p, int(11 * scale)), SQ.look_plan(40, 1.5, 8192, 0.01, 0.05), 0.01)
    ints = SQ.intervals(st)
    truth = dict(zip(SQ.ALL, [*p[0], p_any(p)[0]]))
    for ev, (_, lo, hi) in ints.items():
        covered = np.mean((lo <= truth[ev]) & (truth[ev] <= hi))
        assert covered >= 0.93, f"{ev}: the interval covers the truth in {covered:.1%} of 200"
    assert len(set(st.n.tolist())) > 1  # the repetitions stopped at different looks: the looks were used


def test_a_wald_interval_would_fail_the_same_check():  # the check above can fail
    rng = np.random.default_rng(3)
    k = rng.binomial(200, 0.002, size=200)
    p_hat = k / 200
    half = 1.96 * np.sqrt(p_hat * (1 - p_hat) / 200)
    assert np.mean((p_hat - half <= 0.002) & (0.002 <= p_hat + half)) < 0.93


def test_sequential_stop_reaches_the_decisions_of_a_fixed_large_sample():
    """A map of 60 units, 0.01 % to 50 % (none within a factor 2.5 of p_max): the sequential stop's
    decisions equal those of a fixed sample of the cap, one look each, at far fewer cycles."""
    rng = np.random.default_rng(5)
    lo_side = 10 ** rng.uniform(-4, np.log10(0.004), 30)
    hi_side = 10 ** rng.uniform(np.log10(0.025), np.log10(0.5), 30)
    share = np.concatenate([lo_side, hi_side])
    p = np.column_stack([share * 0.4, share * 0.3, share * 0.2, share * 0.1])
    plan = SQ.look_plan(40, 1.5, 16384, 0.01, 0.05)
    seq = SQ.run_rounds(60, bernoulli(p, 21), plan, 0.01)
    fixed = SQ.run_rounds(60, bernoulli(p, 21), plan, 0.01, sequential=False)
    assert (fixed.decision != SQ.UNDECIDED).all()
    assert (seq.decision == fixed.decision).all()
    assert (seq.decision == np.where(p_any(p) < 0.01, SQ.BELOW, SQ.ABOVE)).all()
    assert fixed.cycles > 5 * seq.cycles


def test_fixed_size_for_finds_the_smallest_size_and_the_least_sizes_bound_the_stop():
    p = np.column_stack([np.array([0.0005, 0.3, 0.0]), np.zeros(3), np.zeros(3), np.zeros(3)])
    st = SQ.run_rounds(3, bernoulli(p, 2), SQ.look_plan(40, 1.5, 8192, 0.01, 0.05), 0.01)
    cum = np.cumsum(bernoulli(p, 2)(np.arange(3), 0, 8192).any(axis=2), axis=1)
    n, asked = SQ.fixed_size_for(st.decision, cum, 0.01, 0.05)
    assert asked.all() and n <= st.n.max()
    assert (SQ.decide(cum[:, n - 1], n, 0.01, 0.05) == st.decision).all()
    assert (SQ.decide(cum[:, n - 2], n - 1, 0.01, 0.05) != st.decision).any()
    least = SQ.least_sizes(st.decision, cum, 0.01, 0.05)
    assert (least <= st.n).all() and least.max() == n
    assert least[2] == SQ.zero_break_size(0.01, 0.05) == 368  # no failure: ln(0.025) / ln(0.99) = 367.04


def test_the_look_plan_spends_alpha_once_and_looks_where_a_decision_can_be_made():
    sizes, alphas = SQ.look_plan(40, 1.5, 8192, 0.01, 0.05)
    assert sum(alphas) == pytest.approx(0.05) and len(sizes) == len(alphas)
    assert sizes[0] == 40 and sizes[-1] == 8192 and all(a < b for a, b in zip(sizes, sizes[1:]))
    assert alphas[0] == pytest.approx(SQ.SCREEN * 0.05) and alphas[1] == pytest.approx(2 * alphas[2])
    n2 = sizes[1]  # the first size at which a unit without a failure is decided below at alpha_2
    assert SQ.decide(0, n2, 0.01, alphas[1]) == SQ.BELOW and SQ.decide(0, n2 - 1, 0.01, alphas[1]) == ""
    assert SQ.look_plan(100, 2, 50, 0.01, 0.05) == ([50], [0.05])


def test_clopper_pearson_at_the_edges():
    lo, hi = SQ.clopper_pearson(0, 100, 0.05)
    assert lo == 0 and hi == pytest.approx(1 - 0.025 ** (1 / 100))
    lo, hi = SQ.clopper_pearson(100, 100, 0.05)
    assert hi == 1 and lo == pytest.approx(0.025 ** (1 / 100))


# ------------------------------------------------------------------ the draws
def test_draws_are_seeded_and_a_longer_run_extends_a_shorter_one():
    sp = RS.parse(spec())
    a, b = PO.draw(sp.population, 50), PO.draw(sp.population, 20)
    for c in PO.SIZES + PO.PLACES:
        assert np.array_equal(a[c][:20], b[c])
    assert ((a["L"] >= 0.2) & (a["L"] <= 0.7)).all() and ((a["m1"] >= 5) & (a["m1"] <= 15)).all()
    room = 0.7 - a["A"]
    assert ((a["dP"] >= 0) & (a["dP"] <= room)).all() and a["dP"].max() > 0.5 * room.max()
    other = RS.parse(spec(population=dict(BASE["population"], seed=8)))
    assert not np.array_equal(PO.draw(other.population, 20)["L"], b["L"])


# ------------------------------------------------------------------ the real engine
@pytest.fixture(scope="module")
def small_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("risk") / "risk.parquet"
    return fencesweep.risk(spec(), out=out, jobs=1, progress=False), out


def test_estimate_equals_a_brute_force_count_of_the_same_parcels_through_grid(small_run, tmp_path):
    df, _ = small_run
    sp = RS.parse(spec())
    parcels = PO.draw(sp.population, sp.cap)
    assert (parcels["phi0"] == 0).all()  # an axis repeats no value: phi0 goes under params
    brute = fencesweep.grid({"params": {"drive": "flexible", "t_c": 1.36, "v": 2.0, "phi0": 0.0},
                             "zip": {c: [float(x) for x in parcels[c]] for c in ("L", "A", "m1", "dP", "R_s")},
                             "cases": [dict(e) for e in BASE["elements"]]},
                            out=tmp_path / "brute.parquet", jobs=1, verify=False, progress=False)
    for (_, row), element in zip(df.iterrows(), BASE["elements"]):
        b = brute[(brute.B2 == element["B2"]) & (brute.K2 == element["K2"])]
        assert len(b) == row["n"] == 12
        counts = {"overload": (b.overload.fillna(0) > 1).sum(), "not_scraped": (b.outcome != "scraped").sum(),
                  "deflection": (b.deflection_max > b.dalpha_perm).sum(),
                  "residual": (b.residual_amplitude > 0.0174533).sum()}
        counts["any"] = (np.column_stack([b.overload.fillna(0) > 1, b.outcome != "scraped",
                                          b.deflection_max > b.dalpha_perm,
                                          b.residual_amplitude > 0.0174533]).any(axis=1)).sum()
        for ev, k in counts.items():
            assert row[f"n_{ev}"] == k, ev
        assert row["p_any"] == pytest.approx(counts["any"] / 12)
    assert df["n_any"].sum() > 0  # the comparison saw failures


def test_the_table_has_units_provenance_and_samples(small_run):
    df, out = small_run
    assert df.attrs["units"]["B2"] == "N m s/rad" and df.attrs["units"]["in_10000_any"] == "parcels in 10,000"
    prov = df.attrs["fencesweep"]
    assert prov["risk"]["looks"] == 1 and "Clopper-Pearson" in prov["risk"]["interval"]
    assert prov["population"]["seed"] == 7 and prov["spec_hash"] == RS.parse(spec()).hash
    assert (df["p_any_lo"] <= df["p_any"]).all() and (df["p_any"] <= df["p_any_hi"]).all()
    samples = fencesweep.read_table(out.with_name("risk_samples.parquet"))
    assert len(samples) == 24 and {"L", "A", "m1", "dP", "R_s", "B2", "outcome"} <= set(samples.columns)
    assert not out.with_name(out.name + ".partial").exists()


def test_the_same_table_for_any_jobs(small_run, tmp_path, monkeypatch):
    from fencesweep.study.sweep import runs

    monkeypatch.setattr(runs, "SERIAL_BELOW", 0.0)  # the two workers run even this little work
    df, out = small_run
    two = fencesweep.risk(spec(), out=tmp_path / "two.parquet", jobs=2, progress=False)
    assert two.equals(df)
    assert two.attrs["run"]["jobs"] == 2


# ------------------------------------------------------------------ resume, with a stand-in engine
def _fake(vals, trajectory=False):
    return {"outcome": "scraped" if vals["R_s"] < 0.59 else "escaped", "overload": vals["m1"] / 20.0,
            "deflection_max": 0.1, "residual_amplitude": 0.001, "peak_force": 1.0, "n_steps": 10,
            "status": "ok", "dalpha_perm": vals["dalpha_perm"]}, None


def test_a_killed_run_keeps_its_rounds(tmp_path):
    d = spec(risk={"p_max": 0.01, "first": 40, "cap": 640})
    calls = {"n": 0}

    def dies(vals, trajectory=False):
        calls["n"] += 1
        if calls["n"] > 400:  # in the second round, after its first chunk (40 per element, then 256)
            raise KeyboardInterrupt
        return _fake(vals)

    out = tmp_path / "r.parquet"
    with pytest.raises(fencesweep.SweepInterrupted) as exc:
        fencesweep.risk(d, out=out, jobs=1, progress=False, simulate=dies)
    assert exc.value.saved >= 2 and not out.exists()
    again = fencesweep.risk(d, out=out, jobs=1, progress=False, simulate=_fake)
    assert again.attrs["run"]["chunks_reused"] >= 2
    clean = fencesweep.risk(d, out=tmp_path / "clean.parquet", jobs=1, progress=False, simulate=_fake)
    assert again.equals(clean) and clean.attrs["run"]["chunks_reused"] == 0


# ------------------------------------------------------------------ bad input
def _write(tmp_path, d: dict):
    import yaml

    path = tmp_path / "risk.yaml"
    path.write_text(yaml.safe_dump(d))
    return path


def _parcels(tmp_path, text: str):
    path = tmp_path / "parcels.csv"
    path.write_text(text)
    return str(path)


GOOD_CSV = "L,A,m1\n0.3,0.12,8\n0.5,0.15,12\n0.25,0.1,6\n0.6,0.18,14\n0.4,0.11,9\n"


@pytest.mark.parametrize("csv, message", [
    ("L,A\n0.3,0.1\n", "missing column m1"),
    ("L,A,m1\n0.3,0.1,8\n0.4,-0.1,9\n", "row 2 (of 2, counting parcels from 1): A = '-0.1' is not allowed"),
    ("L,A,m1\n0.3,0.1,8\n0.4,0.1,9\n0.2,0.1,heavy\n", "row 3 (of 3, counting parcels from 1): m1 = 'heavy'"),
    ("L,A,m1\n0.3,0.1,8\n0.4,0.1,9\n0.2,0.1,5\n1.0,0.8,9\n0.2,0.9,5\n",
     "2 of 5 parcels are wider than the belt and are refused, e.g. row 4"),
])
def test_a_bad_parcels_file_is_one_line_exit_2_nothing_written(tmp_path, capsys, csv, message):
    pop = {"parcels": _parcels(tmp_path, csv), "seed": 1}
    path = _write(tmp_path, spec(population=pop, output=str(tmp_path / "out.parquet")))
    assert main(["risk", str(path)]) == 2
    err = capsys.readouterr().err
    assert message in err and len(err.strip().splitlines()) == 1 and "Traceback" not in err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["parcels.csv", "risk.yaml"]


@pytest.mark.parametrize("column, message", [
    ({"dist": "lognormal", "s": 0.3, "min": 5, "max": 15}, "unknown distribution 'lognormal'; did you mean 'lognorm'?"),
    ({"dist": "lognorm", "sigma": 0.3, "min": 5, "max": 15}, "unknown parameter 'sigma' of scipy.stats.lognorm"),
    ({"dist": "norm", "loc": 10, "scale": 1, "min": -5, "max": 15}, "population.m1.min"),
    ({"dist": "norm", "loc": 10}, "give its bounds"),
])
def test_a_bad_distribution_is_named(tmp_path, capsys, column, message):
    path = _write(tmp_path, spec(population=dict(BASE["population"], m1=column),
                                 output=str(tmp_path / "out.parquet")))
    assert main(["risk", str(path)]) == 2
    err = capsys.readouterr().err
    assert message in err and len(err.strip().splitlines()) == 1
    assert sorted(p.name for p in tmp_path.iterdir()) == ["risk.yaml"]


def test_too_large_parcels_are_left_out_and_counted_when_asked(tmp_path):
    csv = GOOD_CSV + "1.0,0.8,9\n"
    d = spec(population={"parcels": _parcels(tmp_path, csv), "too_large": "skip", "seed": 1},
             risk={"p_max": 0.5, "first": 20, "cap": 20})
    sp = RS.parse(d)
    assert sp.population.left_out == [6] and len(sp.population.parcels["L"]) == 5
    drawn = PO.draw(sp.population, 200)
    assert set(np.round(drawn["A"], 6)) <= {0.12, 0.15, 0.1, 0.18, 0.11}
    notes = []
    df = fencesweep.risk(d, out=tmp_path / "r.parquet", jobs=1, progress=False, simulate=_fake, log=notes.append)
    assert df.attrs["fencesweep"]["population"]["n_file_rows_left_out"] == 1
    assert notes == [f"note: 1 of 6 parcels of {d['population']['parcels']} are wider than the belt and are left out "
                     f"(population.too_large: skip), e.g. row 6"]


def test_distribution_bounds_wider_than_the_belt_are_refused_or_left_out():
    pop = dict(BASE["population"], A={"min": 0.1, "max": 0.9})
    with pytest.raises(fencesweep.SpecError, match="spans 0.9 m across the belt > P_max = 0.7 m"):
        RS.parse(spec(population=pop))
    sp = RS.parse(spec(population=dict(pop, too_large="skip")))
    drawn, fewer = PO.draw(sp.population, 100), PO.draw(sp.population, 30)
    assert drawn["A"].max() <= 0.7 and drawn["too_large"] > 0 and drawn["drawn"] == 100 + drawn["too_large"]
    assert all(np.array_equal(drawn[c][:30], fewer[c]) for c in PO.SIZES + PO.PLACES)  # redrawn in stream order


@pytest.mark.parametrize("change, message", [
    ({"elements": {"B3": [1, 2]}}, "unknown parameter 'B3'; did you mean 'B2'?"),
    ({"elements": [{"L": 0.3}]}, "L is drawn from the population"),
    ({"risk": {"p_max": 2}}, "risk.p_max = 2"),
    ({"risk": {"cap": 10, "first": 64}}, "risk.cap = 10: must be >= risk.first = 64"),
    ({"operating": {"t_c": 1.36, "w": 2}}, "operating[0]"),
    ({"population": dict(BASE["population"], sigma=1)}, "population.sigma: unknown key"),
    ({"population": dict(BASE["population"], m1={"dist": "lognorm", "s": "wide", "min": 5, "max": 15})},
     "population.m1.s = 'wide': expected a finite number"),
])
def test_a_bad_spec_is_named(change, message):
    with pytest.raises(fencesweep.SpecError) as exc:
        RS.parse(spec(**change))
    assert message in str(exc.value)


def test_dask_gives_the_local_table(tmp_path):
    distributed = pytest.importorskip("distributed")
    from helpers import fake_engine

    d = spec(risk={"p_max": 0.05, "first": 12, "cap": 48})
    local = fencesweep.risk(d, out=tmp_path / "local.parquet", jobs=1, progress=False, simulate=fake_engine)
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=":0") as cl:
        far = fencesweep.risk(d, out=tmp_path / "dask.parquet", backend="dask", scheduler=cl.scheduler_address,
                              progress=False, simulate=fake_engine)
    assert far.equals(local) and far.attrs["run"]["jobs"] is None
    assert local["n_any"].sum() > 0 and (local["looks"] >= 1).all()


def test_the_command_prints_the_least_risk_and_the_compared_elements(tmp_path, capsys):
    d = spec(compare={"paper 72/570": {"B2": 72, "K2": 570}}, output=str(tmp_path / "r.parquet"))
    assert main(["risk", str(_write(tmp_path, d)), "--jobs", "1", "--quiet"]) == 0
    assert capsys.readouterr().out == ""  # --quiet: no summary
    assert main(["risk", str(_write(tmp_path, d)), "--jobs", "1"]) == 0
    out = capsys.readouterr().out.splitlines()
    assert out[0].startswith(f"wrote {tmp_path / 'r.parquet'}: 3 elements x operating points, 36 cycles")
    assert out[1].startswith("least risk (the lowest upper end) (B2 = ") and "parcels in 10,000" in out[1]
    assert out[2].startswith("paper 72/570 (B2 = 72, K2 = 570; t_c = 1.36 s, v = 2 m/s): ")


def test_another_specs_table_or_unfinished_run_is_not_replaced(tmp_path):
    d = spec(risk={"p_max": 0.01, "first": 40, "cap": 640})
    calls = {"n": 0}

    def dies(vals, trajectory=False):
        calls["n"] += 1
        if calls["n"] > 100:
            raise KeyboardInterrupt
        return _fake(vals)

    out = tmp_path / "r.parquet"
    with pytest.raises(fencesweep.SweepInterrupted):
        fencesweep.risk(d, out=out, jobs=1, progress=False, simulate=dies)
    other = spec(risk={"p_max": 0.02, "first": 40, "cap": 640})
    with pytest.raises(fencesweep.UsageError, match="unfinished run of another risk spec"):
        fencesweep.risk(other, out=out, jobs=1, progress=False, simulate=_fake)
    fencesweep.risk(other, out=out, jobs=1, progress=False, simulate=_fake, overwrite=True)
    with pytest.raises(fencesweep.UsageError, match="is not a table of this risk spec"):
        fencesweep.risk(d, out=out, jobs=1, progress=False, simulate=_fake)


def test_the_report_section_and_the_map_are_read_off_the_table(tmp_path):
    from fencesweep.report.risk_text import risk_section

    res = tmp_path / "res"
    assert risk_section(res) == []  # nothing before `fencesweep risk` has run
    d = spec(elements={"B2": [15, 231], "K2": [925, 2075]}, compare={"envelope 231/925": {"B2": 231, "K2": 925}},
             risk={"p_max": 0.01, "first": 40, "cap": 320})
    df = fencesweep.risk(d, out=res / "risk.parquet", jobs=1, progress=False, simulate=_fake)
    text = "\n".join(risk_section(res))
    row = df[df.label == "envelope 231/925"].iloc[0]
    assert f"| envelope 231/925 | 231 / 925 | 1.36 / 2 | **{row['in_10000_any']:.0f}** " in text
    assert (f"envelope 231/925 hits {row['in_10000_overload']:.0f} too hard and does not sort "
            f"{row['in_10000_not_scraped']:.0f} (") in text
    assert "R_s uniform from -0.4 to 0.6 m" in text and "seed 7" in text and "**assumed**" in text
    assert "Least risk: B2 = " in text and "parcels in 10,000" in text
    pytest.importorskip("matplotlib")
    from fencesweep.report.design_figures import plot

    [png] = plot(["risk_map"], res, tmp_path / "figures")
    assert png.name == "risk_map.png" and png.stat().st_size > 10_000
