"""Figures and the report render headless from small synthetic tables and trajectories.

No engine runs here: the inputs are tiny DataFrames with the columns the engine writes
(sweep tables: docs/model.md §11/§12 names; trajectories: scenes.cycle.TRAJ_COLUMNS), so the
test checks the drawing and the bookkeeping, fast.
"""
from __future__ import annotations

import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from fencesweep.model import params as P
from fencesweep.report import analysis as RP
from fencesweep.report import document as DOC
from fencesweep.report import fig5a_text as F5A
from fencesweep.report import maps_text as MT
from fencesweep.study.store import table as store

pytest.importorskip("matplotlib")

PNG = b"\x89PNG\r\n\x1a\n"


# ---------------------------------------------------------------------------- synthetic inputs
def _tables(res: Path) -> None:
    rows = []
    for case in RP.CASES:
        for B2 in (0.0, 50.0, 100.0, 150.0):
            for K2 in (500.0, 1000.0, 1500.0):
                psi = P.relative_damping(B2, K2, 2.4)
                rows.append(dict(case=case, B2=B2, K2=K2, Psi=0.9 if (B2, K2) == (50.0, 1000.0) else psi,
                                 overload=0.6 + B2 / 1000 + (0.3 if case == "small_far" else 0.0) * (K2 < 600),
                                 deflection_max=math.radians(10.0 - B2 / 20), residual_deflection=math.radians(500 / K2),
                                 residual_amplitude=math.radians(500 / K2),
                                 dalpha_perm=math.radians(15.0), damper_energy=B2 / 10, x_exit=1.0, contact_time=0.1,
                                 outcome="escaped" if (B2 == 150.0 and K2 == 500.0) else "scraped"))
    pd.DataFrame(rows).to_parquet(res / "b2k2.parquet")
    psi = [dict(case=c, B2=b, K2=(b / 2) ** 2 / 2.4, damper_energy=b / 10 if c == "small_far" else 10 / b,
                deflection_max=math.radians(200 / b), dalpha_perm=math.radians(15.0),
                outcome="scraped" if b > 20 else "escaped") for c in RP.CASES for b in (10.0, 50.0, 100.0, 200.0)]
    pd.DataFrame(psi).to_parquet(res / "psi_b2.parquet")
    f5a = []
    for case in RP.CASES:
        for drive, k in (("rigid", 1.0), ("flexible", 0.7), ("free", 0.65)):
            for t_c in (1.0, 1.36, 2.0):
                for v in (1.0, 2.0, 3.0):
                    ov = k * v / 2 * (1.36 / t_c)
                    f5a.append(dict(case=case, drive=drive, t_c=t_c, v=v, overload=ov, peak_force=ov * 6414.0,
                                    outcome="scraped" if drive != "free" else "escaped",
                                    t_first_contact=0.46 if case == "small_far" else 0.0, contact_time=0.1,
                                    n_impacts=1, R_s=0.0, dP=0.6 if case == "small_far" else 0.0, l=1.2, A=0.1))
    pd.DataFrame(f5a).to_parquet(res / "fig5a.parquet")
    for name, axis in RP.WORST_TABLES.items():  # the worst-case placements of Fig. 5a: two per point of a cut
        vals = (1.0, 2.0, 3.0) if axis == "v" else (1.0, 1.36, 2.0)
        rows = [dict(drive=drive, v=x if axis == "v" else 2.0, t_c=x if axis == "t_c" else 1.36, dP=dP, R_s=0.0,
                     overload=k * (1.2 if dP == 0.5 else 1.0), peak_force=k * 6414.0, outcome="scraped",
                     t_S3=0.01 if (drive == "rigid" and dP == 0.5) else 0.0)
                for drive, k in (("rigid", 1.1), ("flexible", 0.7), ("free", 0.65)) for x in vals for dP in (0.5, 0.6)]
        pd.DataFrame(rows).to_parquet(res / f"{name}.parquet")
    f5b = [dict(m2=m, drive=d, peak_force=5087.0 if d == "rigid" else 5087.0 / (1 + 3.7 / m ** 0.5))
           for m in (1.0, 5.0, 50.0) for d in ("rigid", "free", "flexible")]
    pd.DataFrame(f5b).to_parquet(res / "fig5b.parquet")
    H = np.round(np.arange(0.02, 0.41, 0.02), 2)
    pd.DataFrame(dict(H=H, peak_force=6414.0 * (H / 0.3) ** 0.6)).to_parquet(res / "freefall_H.parquet")


def _trajectory(case: str, over: dict) -> tuple[pd.DataFrame, dict, dict]:
    """A plausible cycle: S2, an impact (S1), S3, S2, exit; alpha lagging a cosine drive."""
    vals = P.resolve("cycle", case, **over)
    tc = vals["t_c"]
    A, B, tx = (0.4, 0.5, 0.55) if case == "small_far" else (0.0, 0.6, 0.7)
    t = np.unique(np.r_[np.linspace(0, tc, 300), np.linspace(A, A + 0.012, 60)])
    aw = vals["swing"] / 2 * (1 - np.cos(2 * np.pi * t / tc))
    lag = 0.0 if vals["drive"] == "rigid" else 0.03
    al = aw - lag * np.sin(2 * np.pi * t / tc)
    pulse = np.where((t >= A) & (t <= A + 0.01), 5000 * np.clip(np.sin(np.pi * (t - A) / 0.01), 0, 1) ** 0.5, 0.0)
    slide = np.where((t > A + 0.01) & (t < B), 100.0, 0.0)
    nf = pulse + slide
    stage = np.where(t < A, 1, np.where(t < A + 0.03, 3 if case == "long_near" else 0,
                                        np.where(t < B, 2, np.where(t < tx, 1, -1)))).astype("int8")
    nr = np.where(stage == 3, 50.0, 0.0)
    x0 = vals["R_s"] - vals["L"] / 2
    df = pd.DataFrame(dict(t=t, x=x0 + vals["v"] * np.minimum(t, tx), y=vals["dP"] + vals["A"] / 2 + 0.1 * (t > A) * np.minimum(t - A, tx - A),
                           phi=0.0, vx=vals["v"], vy=0.0, omega=0.0, alpha=al, alpha_w=aw,
                           alpha_dot=np.gradient(al, t), N_fence=nf, N_rail=nr, M_fence=nf * 0.9, stage=stage,
                           E_damper=0.0, E_contact=0.0, W_drive=0.0, W_belt=0.0, E_friction=0.0))
    res = dict(outcome="scraped", t_exit=tx, peak_force=float(nf.max()), freefall_force=6414.0,
               overload=float(nf.max()) / 6414.0, deflection_max=0.05, residual_deflection=0.02, residual_amplitude=0.021,
               t_first_contact=A, contact_time=B - A, x_exit=1.0, damper_energy=1.0)
    return df, vals, res


def _trajectories(res: Path) -> None:
    (res / "traj").mkdir()
    for name, (case, over) in RP.TRAJECTORIES.items():
        df, vals, r = _trajectory(case, over)
        store.write_trajectory(df, RP.traj_path(res, name), vals, r)


@pytest.fixture(scope="module")
def results(tmp_path_factory) -> Path:
    res = tmp_path_factory.mktemp("results")
    _tables(res)
    _trajectories(res)
    return res


# ---------------------------------------------------------------------------- tests
def test_plot_all_writes_every_png(results):
    from fencesweep.report import figures as plots

    out = results / "figures"
    paths = plots.plot(["all"], results, out)
    assert len(paths) == plots.N_FILES == len(set(paths))
    assert sorted(out.glob("*.png")) == sorted(paths)
    for p in paths:
        assert p.stat().st_size > 5000
        assert p.read_bytes()[:8] == PNG, p


def test_report_is_written(results):
    path = DOC.write_report(results)
    text = path.read_text()
    for part in ("## 1. The paper's results", "| 6 |", "## 2. Design maps", "**Two-case pick: B2 = 50",
                 "residual_amplitude <= 1 deg", "bash results/regenerate.sh", "## 4. Where our numbers differ"):
        assert part in text, part
    assert "build" not in text  # the element to build is the load envelope's: no design has run here
    assert "nan" not in text.split("## 2.")[1].split("How the choice")[0]


def test_design_constraints_and_choice(results):
    D = RP.design(pd.read_parquet(results / "b2k2.parquet"), residual_max_deg=1.0)
    g = D.grids["small_far"]
    assert g["overload"].shape == (3, 4)  # K2 x B2
    # residual 500 / K2 deg <= 1 everywhere; the escape at B2 = 150, K2 = 500 is the one infeasible cell
    assert not D.feasible["small_far"][0, 3] and D.first_fail[0, 3] == 1
    assert D.both.sum() == 11
    # of the two inner cells only (50, 1000) has no infeasible neighbour
    assert D.robust.sum() == 1 and D.best is not None
    assert (D.best["B2"], D.best["K2"]) == (50.0, 1000.0)
    tight = RP.design(pd.read_parquet(results / "b2k2.parquet"), residual_max_deg=0.3)
    assert not tight.both.any() and tight.best is None


def test_home_is_judged_by_the_residual_amplitude_not_the_snapshot(results):
    df = pd.read_parquet(results / "b2k2.parquet")
    ringing = (df.B2 == 50.0) & (df.K2 == 1000.0)  # caught at a zero crossing: deflection 0, still swinging 3 deg
    df.loc[ringing, "residual_deflection"] = 0.0
    df.loc[ringing, "residual_amplitude"] = math.radians(3.0)
    D = RP.design(df, residual_max_deg=1.0)
    assert not D.feasible["small_far"][1, 1] and D.first_fail[1, 1] == 4
    old = RP.design(df.drop(columns="residual_amplitude"), residual_max_deg=1.0)  # a table from before the result
    assert old.feasible["small_far"][1, 1]


def test_stage_runs_merge_chatter():
    t = np.array([0.0, 0.1, 0.1005, 0.2, 0.3, 0.4])
    df = pd.DataFrame(dict(t=t, stage=np.array([1, 0, 2, 2, 1, -1], dtype="int8")))
    runs = RP.stage_runs(df, min_dur=2e-3)
    assert [s for _, _, s in runs] == [1, 2, 1]  # the 0.5 ms S1 is merged away
    assert runs[-1][1] == pytest.approx(0.4)


def test_cli_plot_and_missing_input(results, tmp_path, capsys):
    from fencesweep.cli import main

    assert main(["plot", "fig5b", "--results", str(results), "--out", str(tmp_path)]) == 0
    assert (tmp_path / "fig5b_quotient_m2.png").read_bytes()[:8] == PNG
    assert main(["plot", "maps", "--results", str(tmp_path / "nowhere")]) == 2
    err = capsys.readouterr().err
    assert "b2k2.parquet is missing" in err and "fencesweep grid sweeps/b2k2.yaml" in err


def test_plots_import_without_matplotlib():
    code = ("import sys; sys.modules['matplotlib'] = None\n"
            "import fencesweep.report.figures, fencesweep.cli\n"
            "ap = fencesweep.cli.build_parser(); ap.parse_args(['plot', 'all'])\n")
    subprocess.run([sys.executable, "-c", code], check=True)


# ---------------------------------------------------------------------------- the report's numbers
def test_report_numbers_follow_the_tables(results, tmp_path):
    """The Fig. 6 sentence is computed from psi_b2 and flips with it; nothing in it is typed."""
    import shutil

    res = tmp_path / "res"
    shutil.copytree(results, res)
    text = DOC.write_report(res).read_text()
    psi = pd.read_parquet(res / "psi_b2.parquet")
    sf = psi[psi.case == "small_far"]
    assert f"to at most {sf.damper_energy.max():.1f} J" in text      # small_far's energy rises with B2 here
    assert "the energy trend depends on the load" in text
    psi.loc[psi.case == "small_far", "damper_energy"] = 10 / psi.B2   # now it falls, like long_near's
    psi.to_parquet(res / "psi_b2.parquet")
    text = DOC.write_report(res).read_text()
    assert "the energy trend is the paper's for both loads" in text
    assert "the energy trend depends on the load" not in text


def test_report_fig5a_section(results):
    text = DOC.write_report(results).read_text()
    part = text.split("### Fig. 5a")[1].split("## 2.")[0]
    w = RP.worst_over_placements(pd.read_parquet(results / "fig5a_worst_v.parquet"))
    wp = w[(w.t_c == 1.36) & (w.v == 2.0)].set_index("drive")
    assert f"{wp.loc['rigid', 'overload']:.3f} (dP = 0.5" in part   # the worst placement's overload, read off
    assert "had two fence contact points at once" in part and "| small_far | free |" in part


def test_worst_over_placements_takes_the_largest():
    df = pd.DataFrame(dict(drive=["rigid"] * 3 + ["free"] * 2, t_c=1.36, v=2.0, dP=[0.1, 0.2, 0.3, 0.1, 0.2],
                           R_s=0.0, overload=[0.5, 0.9, 0.7, 0.4, 0.3], t_S3=[0.0, 0.01, 0.0, 0.0, 0.0]))
    w = RP.worst_over_placements(df).set_index("drive")
    assert w.loc["rigid", "dP"] == 0.2 and w.loc["rigid", "two_points"] and w.loc["rigid", "n_placements"] == 3
    assert w.loc["free", "overload"] == 0.4 and not w.loc["free", "two_points"]


def test_escape_causes_read_off_the_row():
    base = dict(outcome="escaped", drive="rigid", R_s=0.0, dP=0.6, l=1.2, A=0.1, t_c=1.36, n_impacts=1,
                contact_time=0.01, peak_force=1000.0)
    xt = math.sqrt(1.2 ** 2 - 0.6 ** 2)
    rows = [dict(base, outcome="scraped", v=2.0, t_first_contact=0.43),
            dict(base, v=3.0, t_first_contact=math.nan, n_impacts=0),       # never touched
            dict(base, drive="free", v=2.0, t_first_contact=0.43),
            dict(base, v=2.5, t_first_contact=(xt + 0.03) / 2.5),           # corner 3 cm past the tip
            dict(base, v=2.4, t_first_contact=(xt - 0.01) / 2.4),           # corner 1 cm short of it
            dict(base, v=1.0, t_first_contact=0.5, contact_time=0.2),       # B = 0.7 > t_c / 2
            dict(base, v=1.0, t_first_contact=0.3),                         # none of these
            dict(base, drive="free", v=1.0, t_first_contact=math.nan, n_impacts=0, peak_force=5e-15),  # at rest
            dict(base, drive="free", v=3.0, t_first_contact=math.nan, n_impacts=0, peak_force=0.0)]    # never touched
    got = F5A.escape_cause(pd.DataFrame(rows)).tolist()
    assert got == ["", "no_contact", "free", "tip", "at_tip", "late", "other", "rest", "no_contact"]
    assert set(got) - {""} <= set(F5A.ESCAPE_CAUSES)


def test_jump_is_explained_only_when_the_corner_passes_the_tip(results, tmp_path):
    import shutil

    res = tmp_path / "res"
    shutil.copytree(results, res)
    f5a = pd.read_parquet(res / "fig5a.parquet")
    xt = math.sqrt(1.2 ** 2 - 0.6 ** 2)
    jump = (f5a.case == "small_far") & (f5a.v == 3.0)
    f5a.loc[jump, "overload"] *= 0.2                                   # the overload collapses from v = 2 to 3
    f5a.loc[(f5a.case == "small_far") & (f5a.v == 2.0), "t_first_contact"] = (xt - 0.05) / 2.0
    f5a.loc[jump, "t_first_contact"] = (xt + 0.05) / 3.0                # and the corner passes the tip there
    f5a.to_parquet(res / "fig5a.parquet")
    part = DOC.write_report(res).read_text().split("**The jumps")[1].split("**The escapes")[0]
    along_v = part.split("Along t_c")[0]
    assert f"{xt - 0.05:.3f} m before the step and {xt + 0.05:.3f} m after it" in along_v
    assert "already past the tip" in along_v
    f5a.loc[jump, "t_first_contact"] = (xt - 0.1) / 3.0                 # the same jump, the corner short of the tip
    f5a.to_parquet(res / "fig5a.parquet")
    along_v = DOC.write_report(res).read_text().split("**The jumps")[1].split("Along t_c")[0]
    assert "this jump has another cause" in along_v and "already past the tip" not in along_v


def test_residual_reason_is_computed():
    text = MT.residual_reason(1.0, 15.0, 1.2, 0.1)
    assert "6.7% of the permitted deflection (15 deg)" in text and "21 mm off the rail line" in text
    assert "42 mm" in MT.residual_reason(2.0, 15.0, 1.2, 0.1)


def test_report_reads_where_the_worst_placements_peak(results, tmp_path):
    import shutil

    res = tmp_path / "res"
    shutil.copytree(results, res)
    for drive, stage in (("rigid", 2), ("flexible", 0)):
        df, vals, r = _trajectory("small_far", {"drive": drive, "dP": 0.5, "R_s": 0.3})
        df.loc[df["N_fence"].idxmax(), "stage"] = stage
        store.write_trajectory(df, RP.traj_path(res, f"worst_{drive}"), vals, r)
    text = DOC.write_report(res).read_text()
    assert "peak in stage S3 (rigid, dP = 0.5, R_s = 0.3 m" in text and "S1 (flexible, dP = 0.5" in text
