"""Speed against error: the engine and SciPy's solve_ivp at matched error (issue 4).

Error is measured against benchmarks/reference_results.csv (benchmarks/reference.py: the
same model written independently, DOP853 at rtol 1e-10 with event restarts), scene by
scene over benchmarks/validation_scenes.yaml: relative error of peak_force and
deflection_max (relative to max(|ref|, 1e-3 * scale): 1e-3 of the free-fall force for
forces, of dalpha_perm for angles, so that scenes whose reference value is 0 do not divide
by 0), and of t_exit, and the agreement of the outcome. Time is CPU time per cycle.

  engine    : every scene at step_factor 4, 2, 1, 0.5, 0.25, 0.1 (warm: JIT excluded)
  solve_ivp : benchmarks/reference.py, whose right-hand side is plain Python/NumPy as a
              user would write it, with RK45, DOP853 and LSODA at several rtol

    python benchmarks/work_precision.py [--ivp-scenes N] [--jobs 2]

writes results/work_precision.md, results/work_precision.csv and
results/figures/work_precision.png.
"""
from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path

import numpy as np
import pandas as pd
import yaml

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks"))

DEGENERATE = {"long_near_free"}  # grazing with a free fence: the exact force is 0, see the note
ENGINE_FACTORS = (4.0, 2.0, 1.0, 0.5, 0.25, 0.1)
NOTE = ("The engine's error against the reference levels off at about 2e-4 as its step shrinks, although it converges to itself to about 1e-5 (results/convergence.md): a small systematic difference between the two implementations (the reference places the rigid small_far first contact 1.3e-5 s after the exact crossing of the drive angle, which the engine matches to 1e-13 s). The solve_ivp rows run the reference's own code, so they share its choices and do not see that difference; their errors are the more flattering for it.")
IVP_CONFIGS = [("RK45", 1e-4), ("RK45", 1e-6), ("RK45", 1e-8),
               ("DOP853", 1e-4), ("DOP853", 1e-6), ("DOP853", 1e-8),
               ("LSODA", 1e-4), ("LSODA", 1e-6), ("LSODA", 1e-8)]


def scenes() -> list[dict]:
    data = yaml.safe_load((ROOT / "benchmarks" / "validation_scenes.yaml").read_text())["scenes"]
    out = []
    for sc in data:
        sc = dict(sc)
        for k, v in list(sc.items()):  # YAML 1.1 reads 1.0e7 as a string
            if isinstance(v, str) and k not in ("id", "case", "drive", "profile", "contact_law"):
                sc[k] = float(v)
        out.append(sc)
    return out


def errors(res: dict, ref: pd.Series) -> dict:
    dperm = float(ref.get("dalpha_perm", math.radians(15)))
    fscale = 1e-3 * float(ref["freefall_force"])
    e = {}
    e["e_peak_force"] = abs(res["peak_force"] - ref["peak_force"]) / max(abs(ref["peak_force"]), fscale)
    e["e_deflection_max"] = abs(res["deflection_max"] - ref["deflection_max"]) / max(abs(ref["deflection_max"]),
                                                                                     1e-3 * dperm)
    e["e_t_exit"] = abs(res["t_exit"] - ref["t_exit"]) / abs(ref["t_exit"])
    e["outcome_ok"] = res["outcome"] == ref["outcome"]
    return e


def run_engine(scs: list[dict], ref: pd.DataFrame) -> pd.DataFrame:
    import fencesweep
    from make_reference import row_params

    rows = []
    for sf in ENGINE_FACTORS:
        for sc in scs:
            sid = sc["id"]
            # the reference's fully resolved MODEL.md §12 parameters (every value, I2 and
            # t_max explicit, k_lin under the linear law): the engine solves the same problem
            kw = row_params(ref.loc[sid])
            fencesweep.simulate("cycle", step_factor=sf, **kw)  # warm (and cache)
            n = 5
            t = time.process_time()
            for _ in range(n):
                r = fencesweep.simulate("cycle", step_factor=sf, **kw)
            dt = (time.process_time() - t) / n
            rows.append({"solver": "fencesweep RK4", "setting": f"step_factor={sf:g}", "id": sid,
                         "time": dt, "steps": r["n_steps"], **errors(r, ref.loc[sid])})
        print(f"engine step_factor={sf:g} done", flush=True)
    return pd.DataFrame(rows)


def _ivp_one(sc: dict, method: str, rtol: float) -> dict:
    from reference import simulate_reference

    params = {k: v for k, v in sc.items() if k != "id"}
    t = time.process_time()
    r = simulate_reference(params, method=method, rtol=rtol)
    return {"res": r, "time": time.process_time() - t}


def run_ivp(scs: list[dict], ref: pd.DataFrame, jobs: int) -> pd.DataFrame:
    from joblib import Parallel, delayed

    rows = []
    for method, rtol in IVP_CONFIGS:
        outs = Parallel(n_jobs=jobs)(delayed(_ivp_one)(sc, method, rtol) for sc in scs)
        for sc, o in zip(scs, outs):
            r = o["res"]
            rows.append({"solver": f"solve_ivp {method}", "setting": f"rtol={rtol:g}", "id": sc["id"],
                         "time": o["time"], "steps": r.get("n_rhs", np.nan), **errors(r, ref.loc[sc["id"]])})
        print(f"solve_ivp {method} rtol={rtol:g} done", flush=True)
    return pd.DataFrame(rows)


def md_table(df: pd.DataFrame) -> str:
    """A Markdown table (numbers to 3 significant digits)."""
    fmt = lambda x: f"{x:.3g}" if isinstance(x, (float, np.floating)) else str(x)
    rows = ["| " + " | ".join(df.columns) + " |", "|" + "---|" * len(df.columns)]
    rows += ["| " + " | ".join(fmt(x) for x in r) + " |" for r in df.itertuples(index=False)]
    return "\n".join(rows)


def summarise(df: pd.DataFrame) -> pd.DataFrame:
    d = df[~df.id.isin(DEGENERATE)]
    g = d.groupby(["solver", "setting"], sort=False)
    return pd.DataFrame({
        "scenes": g.size(),
        "time per cycle [ms]": g.time.mean() * 1e3,
        "max e(peak_force)": g.e_peak_force.max(),
        "median e(peak_force)": g.e_peak_force.median(),
        "max e(deflection_max)": g.e_deflection_max.max(),
        "median e(deflection_max)": g.e_deflection_max.median(),
        "max e(t_exit)": g.e_t_exit.max(),
        "outcome agreement": g.outcome_ok.mean(),
    }).reset_index()


def plot(summary: pd.DataFrame, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 2, figsize=(11, 4.2))
    for ax, key in zip(axes, ("max e(peak_force)", "max e(deflection_max)")):
        for solver, g in summary.groupby("solver", sort=False):
            ax.loglog(g["time per cycle [ms]"], g[key].clip(lower=1e-12), "o-", label=solver)
            for _, row in g.iterrows():
                ax.annotate(row.setting.split("=")[1], (row["time per cycle [ms]"], max(row[key], 1e-12)),
                            fontsize=7, xytext=(3, 3), textcoords="offset points")
        ax.axhline(1e-3, color="k", lw=0.8, ls="--")
        ax.set_xlabel("CPU time per cycle [ms]")
        ax.set_ylabel(key.replace("e(", "relative error of ").replace(")", "") + " (max over scenes)")
        ax.grid(True, which="both", alpha=0.3)
    axes[0].legend(fontsize=8)
    fig.suptitle("Work-precision against the rtol 1e-10 reference (validation set)")
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--ivp-scenes", type=int, default=0, help="use only the first N scenes for solve_ivp (0: all)")
    ap.add_argument("--jobs", type=int, default=2, help="parallel solve_ivp runs")
    ap.add_argument("--engine-only", action="store_true")
    args = ap.parse_args()
    ref = pd.read_csv(ROOT / "benchmarks" / "reference_results.csv").set_index("id")
    scs = [sc for sc in scenes() if sc["id"] in ref.index]
    df = run_engine(scs, ref)
    if not args.engine_only:
        ivp_scs = scs[: args.ivp_scenes] if args.ivp_scenes else scs
        df = pd.concat([df, run_ivp(ivp_scs, ref, args.jobs)], ignore_index=True)
    out = ROOT / "results"
    out.mkdir(exist_ok=True)
    df.to_csv(out / "work_precision.csv", index=False)
    summary = summarise(df)
    text = ["# Work-precision: fencesweep against solve_ivp", "",
            "Regenerate: `python benchmarks/work_precision.py`. Errors against the independent "
            "reference (benchmarks/reference.py, DOP853, rtol 1e-10), over the validation scenes "
            f"({', '.join(sorted(DEGENERATE))} excluded from the summary: a load grazing a free "
            "fence, whose exact force is 0 and whose computed force is numerical noise). Times "
            "are CPU time per cycle, engine warm.", "",
            md_table(summary), "", NOTE]
    eng = summary[summary.solver.str.startswith("fencesweep") & (summary.setting == "step_factor=1")]
    ivp = summary[summary.solver.str.startswith("solve_ivp")]
    if len(eng) and len(ivp):
        e = eng.iloc[0]
        ok = ivp[(ivp["max e(peak_force)"] <= max(e["max e(peak_force)"], 1e-3))
                 & (ivp["max e(deflection_max)"] <= max(e["max e(deflection_max)"], 1e-3))
                 & (ivp["outcome agreement"] >= e["outcome agreement"])]
        if len(ok):
            best = ok.loc[ok["time per cycle [ms]"].idxmin()]
            text += ["", f"Fastest solve_ivp configuration at least as accurate as the engine's default "
                     f"(or within 1e-3): {best.solver} {best.setting}, {best['time per cycle [ms]']:.1f} ms "
                     f"per cycle against {e['time per cycle [ms]']:.3f} ms: "
                     f"{best['time per cycle [ms]'] / e['time per cycle [ms]']:.0f}x."]
        else:
            text += ["", "No solve_ivp configuration measured here reaches the engine's default accuracy."]
    (out / "work_precision.md").write_text("\n".join(text) + "\n")
    print("\n".join(text))
    plot(summary, out / "figures" / "work_precision.png")


if __name__ == "__main__":
    main()
