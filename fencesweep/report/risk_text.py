"""REPORT.md's risk section (8): how many parcels in 10,000 of a parcel mix each marked element
hits too hard or does not sort, with its interval, and the element of least risk; every number is
read from results/risk.parquet (`fencesweep risk sweeps/risk.yaml`) when the report is written.
Empty until that table exists."""
from __future__ import annotations

from pathlib import Path

from fencesweep.report.risk_figures import least_risk, ties


def _range(p_lo: float, p_hi: float) -> str:
    return f"{p_lo * 1e4:.0f}-{p_hi * 1e4:.0f}"


def _unit(name: str) -> str:
    from fencesweep.model.params import BY_NAME

    return BY_NAME[name].unit


def _column_text(name: str, d) -> str:
    if not isinstance(d, dict):
        return f"{name} = {d}"
    if d["dist"] == "uniform" and d.get("loc") == d["min"] and abs(d["min"] + d.get("scale", 0) - d["max"]) < 1e-12:
        return f"{name} uniform from {d['min']:g} to {d['max']:g} {_unit(name)}"
    args = ", ".join(f"{k} = {v:g}" for k, v in d.items() if k not in ("dist", "min", "max"))
    return f"{name} {d['dist']}({args}) truncated to {d['min']:g} to {d['max']:g} {_unit(name)}"


def _population_text(pop: dict) -> str:
    if "parcels" in pop:
        p = pop["parcels"]
        sizes = (f"L, A, m1 drawn with replacement from the {p['rows']} parcels of `{p['file']}` "
                 f"({p['left_out_too_large']} wider than the belt left out)")
    else:
        sizes = "; ".join(_column_text(c, pop[c]) for c in ("L", "A", "m1"))
    dP = "dP uniform across the belt where the parcel fits" if pop["dP"] == "across" else _column_text("dP", pop["dP"])
    return f"{sizes}; {dP}; {_column_text('R_s', pop['R_s'])}; phi0 = {pop['phi0']:g}; seed {pop['seed']}"


def _row(name: str, r) -> str:
    return (f"| {name} | {r['B2']:g} / {r['K2']:g} | {r['t_c']:g} / {r['v']:g} | **{r['in_10000_any']:.0f}** ({_range(r['p_any_lo'], r['p_any_hi'])}) "
            f"| {r['in_10000_overload']:.0f} ({_range(r['p_overload_lo'], r['p_overload_hi'])}) "
            f"| {r['in_10000_not_scraped']:.0f} ({_range(r['p_not_scraped_lo'], r['p_not_scraped_hi'])}) "
            f"| {r['in_10000_deflection']:.0f} | {r['in_10000_residual']:.0f} | {int(r['n'])} | {r['decision']} |")


def _levels(alphas) -> str:
    """The looks' levels 1 - alpha_k, as a short list (older tables: one alpha for every look)."""
    if not isinstance(alphas, (list, tuple)):
        return f"{1 - alphas:.4g} at each"
    return ", ".join(f"{1 - a:.4g}" for a in alphas[:4]) + (", ..." if len(alphas) > 4 else "")


def risk_section(res: Path) -> list:
    import pandas as pd

    path = Path(res) / "risk.parquet"
    if not path.exists():
        return []
    df = pd.read_parquet(path)
    prov = df.attrs["fencesweep"]
    rk, counts = prov["risk"], prov["counts"]
    L = ["## 8. Risk from a parcel mix: parcels in 10,000", "",
         f"`fencesweep risk {prov.get('spec_path') or 'SPEC'}` ({df['drive'].iloc[0]} drive, "
         + "; ".join(f"t_c = {t:g} s, v = {v:g} m/s" for t, v in df[["t_c", "v"]].drop_duplicates().to_numpy())
         + "). The parcel mix is **assumed**, not measured: "
         f"{_population_text(prov['population'])}. A parcel breaks a constraint when it is hit harder than the "
         f"permitted drop test (overload > {rk['limits']['overload']:g}), is not sorted (outcome not scraped), "
         f"deflects the fence beyond {rk['limits']['deflection_max']} or leaves it ringing (residual_amplitude > "
         f"{rk['limits']['residual_amplitude']:g} rad).", "",
         f"Each element is sampled in rounds ({', '.join(map(str, rk['schedule']))} parcels) until the interval of "
         f"P(any) lies wholly below or above p_max = {rk['p_max']:g} ({rk['p_max'] * 1e4:g} in 10,000). Intervals: "
         f"Clopper-Pearson at a level fixed for each look in advance ({_levels(rk['alpha_per_look'])}), the "
         f"{rk['looks']} looks' alphas summing to {1 - rk['confidence']:.2g}, which by the union bound keeps "
         f"{rk['confidence']:.0%} at the look where an element stops; the draws are "
         f"plain pseudo-random (seeded), the same parcels for every element. {counts['cycles']} cycles in all, "
         f"against {counts['cycles_at_cap']} for every element at the cap "
         f"([`risk_map.png`](figures/risk_map.png), [`risk.md`](risk.md): the cycles the sequential stop saves).", "",
         "| element | B2 / K2 | t_c / v | any, in 10,000 (95 %) | hit too hard | not sorted | deflection | residual | "
         "parcels sampled | against p_max |", "|---|---|---|---|---|---|---|---|---|---|"]
    best = least_risk(df)
    overlap = ties(df, best)
    marked = df[df["label"].notna()]
    L += [_row(r["label"], r) for r in marked.to_dict("records")]
    L += [_row("least risk", best), ""]
    many = len(df[["t_c", "v"]].drop_duplicates()) > 1
    L += ["Under this mix, of 10,000 parcels: " + "; ".join(
        f"{r['label']}" + (f" at t_c = {r['t_c']:g} s, v = {r['v']:g} m/s" if many else "")
        + f" hits {r['in_10000_overload']:.0f} too hard and does not sort {r['in_10000_not_scraped']:.0f} "
        f"({r['in_10000_any']:.0f} break some constraint, 95 %: {_range(r['p_any_lo'], r['p_any_hi'])})"
        for r in marked.to_dict("records")) + ".",
        "",
        f"**Least risk: B2 = {best['B2']:g}, K2 = {best['K2']:g}**, {best['in_10000_any']:.0f} in 10,000 "
        f"(95 %: {_range(best['p_any_lo'], best['p_any_hi'])}, {int(best['n'])} parcels sampled): the element "
        f"whose risk its sample bounds lowest (the smallest upper end of the interval; an element stopped at 0 "
        f"failures after a few hundred parcels has an estimate of 0 but a wider interval). "
        + (f"The intervals of {overlap} other elements overlap its own: the sampling decides each element against "
           f"p_max, it does not rank them; to rank the best, sample them on with a lower p_max. " if overlap else "")
        + f"{(df['decision'] == 'below').sum()} of {len(df)} elements are below p_max, "
        f"{(df['decision'] == 'above').sum()} above, {(df['decision'] == 'undecided').sum()} undecided at the cap.",
        ""]
    return L
