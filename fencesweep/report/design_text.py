"""REPORT.md's design section (7): every number is read from the tables in results/ when
the report is written (recommended.json and comparison.parquet of `fencesweep design`, the
envelope sweep's per-design-point table, the two-case map b2k2.parquet, swing.parquet,
window_points.parquet, sensitivity.parquet); nothing is typed in here.
"""
from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np

from fencesweep.study.spec import envelope as E


def _deg(x: float) -> str:
    return f"{math.degrees(x):.2f} deg"


def _load_text(load: dict) -> str:
    from fencesweep.model.params import BY_NAME

    parts = []
    for k, v in load.items():
        if k in ("R_s", "phi0") and v == 0:
            continue
        unit = BY_NAME[k].unit if k in BY_NAME else "-"
        parts.append(f"{k} = {v:.3g}" + ("" if unit in ("-", "") else f" {unit}"))
    return ", ".join(parts)


def _envelope_text(rec: dict) -> str:
    env = rec["envelope"]
    dims = []
    for name, d in env["dims"].items():
        if isinstance(d, dict):
            dims.append(f"{name} {d['min']:g}-{d['max']:g}")
        elif d == E.ACROSS:
            dims.append(f"{name} anywhere across the belt (0 to P_max minus the load's width)")
        elif isinstance(d, list):
            dims.append(f"{name} one of {', '.join(map(str, d))}")
        else:
            dims.append(f"{name} = {d:g}")
    sample = next(k for k in ("sobol", "lhs") if k in env)
    return (f"{'; '.join(dims)} (SI units): the {'corners of the box plus ' if env['corners'] else ''}"
            f"{env[sample]} scrambled {sample.capitalize()} points (seed {env['seed']}), {env['n_loads']} loads")


def _comparison(res: Path, rec: dict) -> list:
    import pandas as pd

    cmp = pd.read_parquet(res / "design" / "comparison.parquet")
    out = ["| element | loads scraped | worst overload | worst deflection_max | worst residual_amplitude | "
           "smallest margin | binding | keeps every constraint | worst load for the overload |",
           "|---|---|---|---|---|---|---|---|---|"]
    for _, r in cmp.iterrows():
        nums = "" if pd.isna(r.get("B2")) else f"{r['B2']:g}/{r['K2']:g}"
        elem = r["design"] + (f" ({nums})" if nums and nums not in r["design"] else "")
        load = json.loads(r["worst_overload_load"])
        out.append(f"| {elem} | {int(round(r['share_scraped'] * r['n_loads']))} of {int(r['n_loads'])} | "
                   f"{r['worst_overload']:.3f} | {_deg(r['worst_deflection_max'])} | "
                   f"{_deg(r['worst_residual_amplitude'])} | {r['min_margin']:+.3f} | {r['binding']} | "
                   f"{'yes' if r['feasible'] else 'no'} | {_load_text(load)} |")
    if "stream_n_cycles" in cmp and cmp["stream_n_cycles"].notna().any():
        n = int(cmp["stream_n_cycles"].dropna().iloc[0])
        out += ["", f"The same {n} loads back to back, one per work cycle at period t_c (scene `stream`, "
                "docs/model.md §14, "
                "in the sample's order: what one cycle leaves in the element is what the next starts from). Safe: every "
                "cycle scraped within the overload and deflection limits (as in section 6); the start amplitude is "
                "what the residual_amplitude criterion stands for.", "",
                "| element | scraped | worst overload | worst deflection_max | largest start amplitude | safe |",
                "|---|---|---|---|---|---|"]
        for _, r in cmp[cmp["stream_n_cycles"].notna()].iterrows():
            out.append(f"| {r['design']} | {int(r['stream_n_scraped'])} of {n} | {r['stream_worst_overload']:.3f} | "
                       f"{_deg(r['stream_worst_deflection'])} | {_deg(r['stream_worst_start_amplitude'])} | "
                       f"{'yes' if r['stream_safe'] else 'no'} |")
    return out


def _region(res: Path, rec: dict) -> list:
    """The robust feasible region of the envelope sweep against the two-case maps."""
    import pandas as pd

    pts = pd.read_parquet(res / "envelope_points.parquet")
    n, feas = len(pts), int(pts["feasible"].sum())
    best = pts.loc[pts["min_margin"].idxmax()]
    binds = pts.loc[~pts["feasible"], "binding"].value_counts()
    lines = [f"Over the B2 x K2 grid of `sweeps/envelope.yaml` ({pts['B2'].nunique()} x {pts['K2'].nunique()} elements, "
             f"B2 {pts['B2'].min():g}-{pts['B2'].max():g} N m s/rad, K2 {pts['K2'].min():g}-{pts['K2'].max():g} N m/rad, "
             f"{int(pts['n_loads'].iloc[0])} loads each: {int(pts['n_loads'].sum())} cycles) **{feas} of {n} elements keep "
             f"every constraint for every load** ([`envelope_map.png`](figures/envelope_map.png)). The largest smallest "
             f"margin on the grid is {best['min_margin']:.3f}, at B2 = {best['B2']:g}, K2 = {best['K2']:g}. Where the "
             "constraints are broken, the one that binds: "
             + ", ".join(f"{k} at {v} elements" for k, v in binds.items()) + "."]
    two = res / "b2k2.parquet"
    if two.exists():
        from fencesweep.report import analysis as RP

        D = RP.design(pd.read_parquet(two), math.degrees(rec["constraints"]["residual_amplitude"]))
        both = pd.DataFrame({"B2": np.tile(D.B2, len(D.K2)), "K2": np.repeat(D.K2, len(D.B2)),
                             "both": np.asarray(D.both).ravel()})
        m = both.merge(pts[["B2", "K2", "feasible"]], on=["B2", "K2"])
        acc = m[m["both"]]
        lines += ["", f"Against the two-case maps of section 3 (the same constraints, small_far and long_near only), on "
                  f"the {len(m)} elements both grids share: the two-case maps accept {len(acc)}, of which "
                  f"**{int(acc['feasible'].sum())} keep every constraint over the envelope** and "
                  f"{len(acc) - int(acc['feasible'].sum())} break one for some load; "
                  f"{int((m['feasible'] & ~m['both']).sum())} elements pass the envelope but not the two named loads."]
    return lines


def _searches(rec: dict) -> str:
    """How the optimum was found: one search, or two with `prefer`."""
    opt, seed = rec["optimizer"], rec["design"]["optimizer"]["seed"]
    ended = (f"{'converged' if opt['converged'] else 'did NOT converge'} after {opt['generations']} generations "
             f"({opt['evaluations']} elements, {opt['cycles']} cycles, {opt['seconds']:g} s)")
    big = rec.get("largest_margin")
    if not big:
        return f"The search (scipy differential_evolution, seed {seed}) {ended}."
    (var, way), = rec["design"]["prefer"].items()
    at = ", ".join(f"{k} = {v:g}" for k, v in big["design_variables"].items())
    return (f"Two searches (scipy differential_evolution, seed {seed}): the first finds the largest smallest margin, "
            f"{big['min_margin']:.3f} at {at} ({big['evaluations']} elements, {big['cycles']} cycles, "
            f"{'converged' if big['converged'] else 'NOT converged'}); the second, for the "
            f"{'least' if way == 'min' else 'largest'} {var} whose smallest margin is within "
            f"{rec['design']['within']:g} of it, {ended}.")


def _recommendation(rec: dict) -> list:
    dv = ", ".join(f"{k} = {v:g}" for k, v in rec["design_variables"].items())
    ver, smp = rec["verification"], rec["optimisation_sample"]
    margins = ", ".join(f"{k} {v:.3f}" for k, v in rec["margins"].items() if v is not None)
    goal = {"max_min_margin": "the element farthest inside every constraint",
            "min_worst_overload": "the least worst overload among the elements that keep every constraint"}
    lines = [f"`fencesweep design sweeps/envelope.yaml` ({rec['objective']}: {goal[rec['objective']]}) recommends "
             f"**{dv}** ({rec['status']}). Margins (1 - worst / limit) over the {ver['n_loads']} loads of a fresh, "
             f"denser sample (seed {ver['seed']}): {margins}; the binding constraint is {rec['worst']['binding']}. "
             "Its worst loads:"]
    for k, load in rec["worst_loads"].items():
        lines.append(f"* {k}: {_load_text(load)}")
    lines += ["", _searches(rec) + f" The recommendation's smallest margin is {smp['min_margin']:.3f} on the "
              f"{smp['n_loads']} loads searched and {ver['min_margin']:.3f} on the {ver['n_loads']} fresh ones "
              f"({ver['min_margin_change']:+.3f})."]
    ref = rec.get("refined_on_verification_sample")
    if ref:
        moved = ", ".join(f"{k} {v:+g} ({rel * 100:+.1f} % of its range)"
                          for (k, v), rel in zip(ref["moved"].items(), ref["moved_relative_to_bounds"].values()))
        lines[-1] += (f" Searched again on the fresh loads (Nelder-Mead from it, {ref['nfev']} evaluations), the "
                      f"optimum moves by {moved}, to a smallest margin of {ref['min_margin']:.3f}.")
    for k, side in rec.get("at_bounds", {}).items():
        lines.append(f"Note: {k} lies at the {side} bound of its search range: the best element may lie beyond it.")
    return lines


def _swing(res: Path) -> list:
    import pandas as pd

    d = pd.read_parquet(res / "swing.parquet")
    d = d.assign(deg=np.round(np.degrees(d["swing"]), 6))
    sf = d[d["case"] == "small_far"].set_index("deg")["overload"].sort_index()
    ln = d[d["case"] == "long_near"].set_index("deg")["overload"].sort_index()
    slope = float(np.polyfit(sf.index, sf.to_numpy(), 1)[0])
    at = lambda s, x: float(np.interp(x, s.index, s.to_numpy()))  # noqa: E731
    limit = float(np.interp(1.0, sf.to_numpy(), sf.index)) if sf.max() > 1 > sf.min() else math.nan
    return [f"**The swing is calibrated, not measured.** docs/model.md §12 fixes the drive's swing at 42 deg "
            f"so that the "
            f"rigid fence keeps small_far within the permitted overload, as the paper states; the rigid overload of "
            f"small_far is therefore a consequence of that choice: {at(sf, 42):.3f} at 42 deg, and it grows by "
            f"{slope:.4f} per degree ({at(sf, sf.index.min()):.3f} at {sf.index.min():g} deg, {at(sf, 38):.3f} at "
            f"38 deg, {at(sf, 46):.3f} at 46 deg, {at(sf, sf.index.max()):.3f} at {sf.index.max():g} deg; long_near "
            f"{at(ln, 42):.3f} at 42 deg; `results/swing.parquet`). The rigid fence would break the overload "
            f"constraint for small_far at a swing above {limit:.1f} deg. Every overload in this section scales with "
            "the swing in the same way; a user must measure the swing of the real drive before trusting a margin."]


def _whole_width(res: Path, rec: dict) -> list:
    import pandas as pd

    per = pd.read_parquet(res / "design" / "verify_loads.parquet")
    if "dP" not in per or "A" not in per:
        return []
    p_max = float(rec["fixed"].get("P_max", 0.7))
    frac = per["dP"] / (p_max - per["A"])
    out = []
    for d, s in per.assign(frac=frac).groupby("design", sort=False):
        ok = s["outcome"] == "scraped"
        safe = ok & (s["overload"] <= rec["constraints"]["overload"])
        out.append(f"{d}: {int(ok.sum())} of {len(s)} scraped, {int(safe.sum())} scraped within the permitted "
                   f"overload")
    span = f"{frac.min() * 100:.0f}-{frac.max() * 100:.0f} %"
    return [f"**The paper's claim \"loads can be scraped over the whole accessible width of the belt\"**, checked on "
            f"the {per['load'].nunique()} loads of the verification sample (their starts cover {span} of the accessible "
            f"width, dP / (P_max - A)): " + "; ".join(out) + ". "
            + ("Every compared element scrapes every load: the claim holds for scraping over this envelope; whether it "
               "holds within the permitted overload depends on the element (above)."
               if (per["outcome"] == "scraped").all() else
               "Some loads are not scraped by some element: the claim does not hold for every element over this "
               "envelope."), "", "![loads across the belt](figures/envelope_loads.png)"]


def _window(res: Path) -> list:
    import pandas as pd

    from fencesweep.report.design_figures import element_label

    pts = pd.read_parquet(res / "window_points.parquet")
    tc, v = np.sort(pts["t_c"].unique()), np.sort(pts["v"].unique())
    out = [f"`sweeps/window.yaml`: t_c {tc.min():g}-{tc.max():g} s x v {v.min():g}-{v.max():g} m/s "
           f"({len(tc)} x {len(v)}), each judged over the same {int(pts['n_loads'].iloc[0])} loads and constraints "
           "([`window.png`](figures/window.png)). One load per work cycle: 3600 / t_c packages per hour.", "",
           "| element | safe (t_c, v) of " + str(len(tc) * len(v)) + " | shortest safe t_c [s] (at v [m/s]) | packages "
           "per hour | shortest safe t_c at v = 2 m/s [s] |", "|---|---|---|---|---|"]
    for (drive, b2, k2), g in pts.groupby(["drive", "B2", "K2"], sort=False):
        ok = g[g["feasible"]]
        if len(ok):
            best = ok["t_c"].min()
            at_v = ", ".join(f"{x:g}" for x in sorted(ok.loc[ok["t_c"] == best, "v"]))
            at2 = ok.loc[np.isclose(ok["v"], 2.0), "t_c"]
            out.append(f"| {element_label(drive, b2, k2)} | {len(ok)} | {best:g} ({at_v}) | {3600 / best:.0f} | "
                       + (f"{at2.min():g}" if len(at2) else "none") + " |")
        else:
            out.append(f"| {element_label(drive, b2, k2)} | 0 | none | 0 | none |")
    return out + ["", "![operating window](figures/window.png)"]


def _sensitivity(res: Path) -> list:
    import pandas as pd

    from fencesweep.study.store import table as store

    df = pd.read_parquet(res / "sensitivity.parquet")
    meta = store.read_metadata(res / "sensitivity.parquet")
    fixed = meta.get("fixed", {})
    elem = f"{fixed.get('B2', float('nan')):g} / {fixed.get('K2', float('nan')):g}"
    conv = {"swing": (math.degrees, " deg"), "k1": (lambda x: x, " N/m^1.5"), "m2": (lambda x: x, " kg")}
    out = [f"Sobol indices (SALib, Saltelli sample n = {meta.get('n')}, seed {meta.get('seed')}: {meta.get('n_points')} "
           f"input sets x {meta.get('n_loads')} loads = {meta.get('cycles')} cycles; `sweeps/sensitivity.yaml`) of the "
           f"element {elem}'s worst results over the envelope to the inputs docs/model.md §12 had to assume "
           "([`sensitivity.png`](figures/sensitivity.png)). S1: the share of the output's variance due to the input "
           "alone; ST: with its interactions (95 % confidence half-widths after +-).", "",
           "| input | range | " + " | ".join(f"{o} S1 / ST" for o in dict.fromkeys(df["output"])) + " |",
           "|---|---|" + "---|" * df["output"].nunique()]
    for name, g in df.groupby("input", sort=False):
        f, unit = conv.get(name, (lambda x: x, ""))
        cells = [f"{r['S1']:.2f} +- {r['S1_conf']:.2f} / {r['ST']:.2f} +- {r['ST_conf']:.2f}" for _, r in g.iterrows()]
        out.append(f"| {name} | {f(g['min'].iloc[0]):.4g} - {f(g['max'].iloc[0]):.4g}{unit} | " + " | ".join(cells) + " |")
    ranked = []
    for o, g in df.groupby("output", sort=False):
        top = g.sort_values("ST", ascending=False)
        lead = top[top["ST"] >= 0.1]["input"].tolist() or top["input"].head(1).tolist()
        lo, hi = g["output_min"].iloc[0], g["output_max"].iloc[0]
        ranked.append(f"{o} ({lo:.3g} to {hi:.3g} over the sample): {', '.join(lead)}")
    pts = res / "sensitivity_runs_points.parquet"
    share = ""
    if pts.exists():
        p = pd.read_parquet(pts)
        broken = p.loc[~p["feasible"], "binding"].value_counts()
        share = (f" Over the whole sample the element keeps every constraint for every load at {int(p['feasible'].sum())} "
                 f"of {len(p)} input sets ({100 * p['feasible'].mean():.0f} %); where it does not, the binding "
                 "constraint is " + ", ".join(f"{k} ({v})" for k, v in broken.items()) + ".")
    negligible = sorted(set(df["input"]) - {i for o, g in df.groupby("output") for i in g[g["ST"] >= 0.05]["input"]})
    out += ["", "**What a user must measure first** (inputs with ST >= 0.1 per output): " + "; ".join(ranked) + "."
            + share + (f" Negligible everywhere (ST < 0.05): {', '.join(negligible)}." if negligible else "")]
    return out + ["", "![sensitivity](figures/sensitivity.png)"]


def _tolerance(res: Path) -> list:
    """The five elements over the envelope widened by trigger-timing and orientation tolerances."""
    import pandas as pd

    from fencesweep.report.design_figures import element_label

    pts = pd.read_parquet(res / "tolerance_points.parquet")
    per = pd.read_parquet(res / "tolerance.parquet", columns=["R_s", "phi0", "outcome"])
    from fencesweep.study.store.table import read_metadata

    meta_env = read_metadata(res / "tolerance_points.parquet")["envelope"]["dims"]
    rs, ph = meta_env["R_s"], meta_env["phi0"]
    out = [f"`sweeps/tolerance.yaml` widens the envelope by a trigger-timing tolerance (R_s {rs['min']:g} to "
           f"{rs['max']:g} m) and an orientation tolerance (phi0 {ph['min']:g} to {ph['max']:g} rad): "
           f"{int(pts['n_loads'].iloc[0])} loads at t_c = 1.36 s, v = 2 m/s.", "",
           "| element | loads not scraped | worst overload | worst deflection_max | worst residual_amplitude | "
           "smallest margin | binding |", "|---|---|---|---|---|---|---|"]
    for _, r in pts.iterrows():
        out.append(f"| {element_label(r['drive'], r['B2'], r['K2'])} | {int(r['n_escaped'])} of {int(r['n_loads'])} | "
                   f"{r['worst_overload']:.3f} | {_deg(r['worst_deflection_max'])} | "
                   f"{_deg(r['worst_residual_amplitude'])} | {r['min_margin']:+.3f} | {r['binding']} |")
    lost = per[per["outcome"] != "scraped"]
    feas = int(pts["feasible"].sum())
    text = (f"{feas} of {len(pts)} elements keep every constraint for every load with these tolerances. ")
    if len(lost):
        below = lost.loc[lost["R_s"] <= 0, "R_s"]
        above = lost.loc[lost["R_s"] > 0, "R_s"]
        text += (f"The {len(lost)} loads not scraped (over all elements) start with R_s "
                 + " or ".join(x for x in ((f"<= {below.max():.3g} m" if len(below) else ""),
                                             (f">= {above.min():.3g} m" if len(above) else "")) if x)
                 + f" (the ends of the timing tolerance; between them no load is lost): every element loses "
                 f"{int(pts['n_escaped'].min())} to {int(pts['n_escaped'].max())} of them.")
    return out + ["", text]


def design_section(res: Path) -> list:
    """The lines of REPORT.md's design section (empty when `fencesweep design` has not run)."""
    res = Path(res)
    path = res / "design" / "recommended.json"
    if not path.exists():
        return []
    rec = json.loads(path.read_text())
    L = ["## 7. Design for every package: a load envelope instead of two named loads", "",
         f"The loads: {_envelope_text(rec)}, at t_c = {rec['fixed'].get('t_c', 1.36):g} s, v = "
         f"{rec['fixed'].get('v', 2.0):g} m/s. Constraints for every load: scraped, overload <= "
         f"{rec['constraints']['overload']:g}, deflection_max <= dalpha_perm, residual_amplitude <= "
         f"{math.degrees(rec['constraints']['residual_amplitude']):.3g} deg. Margins are 1 - worst / limit "
         "(negative: broken). The recommendation, machine-readable, with the loads it was checked on: "
         "[`design/recommended.json`](design/recommended.json).", ""]
    if (res / "envelope_points.parquet").exists():
        L += ["### The robust feasible region", ""] + _region(res, rec) + ["", "![envelope map](figures/envelope_map.png)", ""]
    L += ["### The element to build", ""] + _recommendation(rec) + ["", "### Comparison on the fresh loads", ""]
    L += _comparison(res, rec) + [""]
    L += _whole_width(res, rec) + [""]
    if (res / "tolerance_points.parquet").exists() and (res / "tolerance.parquet").exists():
        L += ["### With trigger-timing and orientation tolerances", ""] + _tolerance(res) + [""]
    if (res / "window_points.parquet").exists():
        L += ["### Operating window and throughput", ""] + _window(res) + [""]
    if (res / "swing.parquet").exists():
        L += ["### The swing", ""] + _swing(res) + [""]
    if (res / "sensitivity.parquet").exists():
        L += ["### Sensitivity to the assumed inputs", ""] + _sensitivity(res) + [""]
    return L
