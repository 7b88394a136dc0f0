"""REPORT.md section 2: the B2 x K2 design maps of the two named cases, their constraints (and why
the residual-amplitude threshold means "the fence is home": residual_reason), the two-case pick and
the well-damped pick read off them (comparisons to the element to build, the load envelope's design
that opens the report), the elements run as single cycles, the paper's element against the
constraints and how the picks move with the threshold. No physics, no matplotlib.
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from fencesweep.report.analysis import (CASES, Design, PAPER_B2, PAPER_K2, RESIDUAL_MAX_DEG, design, read_traj,
                                        traj_path)
from fencesweep.report.inputs import ReportInputs


def residual_reason(threshold_deg: float, perm_deg: float, l: float, a_min: float) -> str:
    """Why a residual amplitude of `threshold_deg` counts as "the fence is home" (design maps)."""
    tip = l * math.sin(math.radians(threshold_deg))
    return (
        "A cycle starts from the rest position the model assumes (alpha = 0 at t = 0), and the next one's "
        "deflection adds to whatever swing is left of this one; residual_amplitude (docs/model.md §11) "
        "is that swing's "
        "undamped amplitude, deflection and rate at t_c together (a snapshot of the deflection alone can catch a "
        f"ringing fence at its zero crossing). {threshold_deg:g} deg is {threshold_deg / perm_deg:.1%} of the "
        f"permitted deflection ({perm_deg:g} deg), so the leftover eats at most that share of the next cycle's "
        f"deflection budget, and it moves the fence tip (l = {l:g} m) {tip * 1e3:.0f} mm off the rail line, "
        f"{tip / a_min:.0%} of the narrowest load side (A = {a_min:g} m); a near-rail load then meets a ramp of at "
        f"most {threshold_deg:g} deg, not a step.")


# ------------------------------------------------------------------ 2. design maps
def maps_section(I: ReportInputs) -> list[str]:
    D, thr = I.D, I.residual_max_deg
    n = D.both.size
    p = I.base
    a_min = min(I.T[f"{c}_flexible"].attrs["params"]["A"] for c in CASES)
    L = ["## 2. Design maps over B2 x K2 and the two-case pick", "",
         f"Table `b2k2.parquet` (`sweeps/b2k2.yaml`): B2 = {D.B2.min():g} to {D.B2.max():g} N m s/rad "
         f"(step {D.B2[1] - D.B2[0]:g}), K2 = {D.K2.min():g} to {D.K2.max():g} N m/rad (step {D.K2[1] - D.K2[0]:g}), "
         f"{n} cells per case, at the paper's working point. A cell is **feasible** when, for the case(s) in "
         "question, every constraint holds:", "",
         "1. the load is scraped (outcome = scraped);",
         f"2. overload <= 1 (peak fence force no more than a drop from H = {p['H']:g} m);",
         f"3. deflection_max <= dalpha_perm = {math.degrees(p['dalpha_perm']):.3g} deg;",
         f"4. **residual_amplitude <= {thr:g} deg** (the fence is home for the next cycle). "
         + residual_reason(thr, math.degrees(p["dalpha_perm"]), p["l"], a_min)
         + ("" if thr == RESIDUAL_MAX_DEG else f" (Threshold set with --residual-max; the default is "
            f"{RESIDUAL_MAX_DEG:g} deg.)"), "",
         "| | small_far | long_near | both |", "|---|---|---|---|",
         f"| feasible cells | {int(D.feasible['small_far'].sum())} | {int(D.feasible['long_near'].sum())} | "
         f"{int(D.both.sum())} of {n} |"]
    for code in range(1, 5):
        cnt = {c: int(_failing(D, c, code, thr).sum()) for c in CASES}
        L.append(f"| cells failing: {Design.FAIL_NAMES[code]} | {cnt['small_far']} | {cnt['long_near']} | |")
    L.append("")
    return L + (_recommendation(I) if D.best else
                ["**No cell keeps every constraint for both cases with a margin of one grid step.**", ""])


def _failing(D: Design, case: str, code: int, thr: float):
    g = D.grids[case]
    return {1: g["outcome"] != "scraped", 2: g["overload"] > 1, 3: g["deflection_max"] > g["dalpha_perm"],
            4: g["residual_deg"] > thr}[code]


def _recommendation(I: ReportInputs) -> list[str]:
    D = I.D
    b, braw, bd = D.best, D.best_raw, D.damped
    L = [f"**Two-case pick: B2 = {b['B2']:g} N m s/rad, K2 = {b['K2']:g} N m/rad** (Psi = {b['Psi']:.2f}): "
         f"the lowest larger-of-the-two overload, {b['worst_overload']:.3f}, among the cells that keep every "
         f"constraint for both cases together with all 8 neighbours (so +-{D.B2[1] - D.B2[0]:g} N m s/rad and "
         f"+-{D.K2[1] - D.K2[0]:g} N m/rad of tolerance on the element keep them too). There: small_far overload "
         f"{b['small_far.overload']:.3f}, deflection_max {b['small_far.deflection_max_deg']:.1f} deg, residual amplitude "
         f"{b['small_far.residual_deg']:.2f} deg; long_near overload {b['long_near.overload']:.3f}, deflection_max "
         f"{b['long_near.deflection_max_deg']:.1f} deg, residual amplitude {b['long_near.residual_deg']:.2f} deg.", ""]
    notes = []
    if braw and (braw["B2"], braw["K2"]) != (b["B2"], b["K2"]):
        notes.append(f"The lowest feasible cell without the neighbour margin is B2 = {braw['B2']:g}, "
                     f"K2 = {braw['K2']:g} (worst overload {braw['worst_overload']:.3f}); it sits on the edge "
                     "of the feasible region or of the grid, so the pick passes it over.")
    if b["K2"] >= D.K2[-2]:
        notes.append(f"The choice sits one step inside the grid's upper K2 bound ({D.K2.max():g} N m/rad): "
                     "the residual-amplitude constraint pushes towards stiff elements, and a wider K2 range "
                     "may hold a slightly lower overload (a stiffer element tends back to the rigid fence, so "
                     "not much lower).")
    if bd:
        notes.append(f"**Well-damped pick** (the same rule within the paper's 0.7 <= Psi <= 1, §4.2): "
                     f"B2 = {bd['B2']:g}, K2 = {bd['K2']:g} (Psi = {bd['Psi']:.2f}), worst overload "
                     f"{bd['worst_overload']:.3f} ({(bd['worst_overload'] / b['worst_overload'] - 1):+.1%} against "
                     "the two-case pick).")
    for s_ in notes:
        L += [s_, ""]
    return L + _three_elements(I)


#: the single cycles of the table under the picks: trajectory tag -> the element's name in the table
#: (analysis.design_runs makes `<case>_envelope`, `<case>_recommended` and `<case>_well_damped`)
CYCLE_ELEMENTS = (("envelope", "to build (load envelope)"), ("flexible", f"paper {PAPER_B2:g}/{PAPER_K2:g}"),
                  ("recommended", "two-case pick"), ("well_damped", "well-damped pick"))


def _cycle_row(res: Path, name: str, what: str, case: str) -> tuple[str, tuple]:
    """One element's single cycle as a table row, and the swing of its deflection after the load has
    left: (min, max, sign changes) [deg]."""
    from fencesweep.model import params as P

    df = read_traj(res, name)
    pr, rr = df.attrs["params"], df.attrs["results"]
    after = df[df["t"] > float(rr["t_exit"])]
    da = np.degrees((after["alpha"] - after["alpha_w"]).to_numpy())
    swing = (float(da.min()), float(da.max()), int((np.diff(np.sign(da)) != 0).sum())) if len(da) else \
        (math.nan, math.nan, 0)
    row = (f"| {what} | {pr['B2']:g} / {pr['K2']:g} | {P.relative_damping(pr['B2'], pr['K2'], pr['I2']):.2f} "
           f"| {case} | {rr['outcome']} | {rr['overload']:.3f} | {math.degrees(rr['deflection_max']):.1f} | "
           f"{swing[0]:+.1f} / {swing[1]:+.1f} | {math.degrees(rr['residual_deflection']):.2f} | "
           f"{math.degrees(rr['residual_amplitude']):.2f} | "
           f"{math.degrees(float(df['alpha_dot'].iloc[-1])):.1f} | {rr['contact_time']:.3f} | {rr['x_exit']:.3f} |")
    return row, swing


def _three_elements(I: ReportInputs) -> list[str]:
    """The element to build, the paper's element and the two picks of the maps run as single cycles
    (those whose trajectories exist), then how the two picks compare after the impact."""
    D, b = I.D, I.D.best
    rows, swing = [], {}
    for tag, what in CYCLE_ELEMENTS:
        for c in CASES:
            if traj_path(I.res, f"{c}_{tag}").exists():
                row, swing[(tag, c)] = _cycle_row(I.res, f"{c}_{tag}", what, c)
                rows.append(row)
    if not rows:
        return []
    L = ["The elements run as single cycles on both named cases (`recommended.png`):", "",
         "| element | B2 / K2 | Psi | case | outcome | overload | deflection_max [deg] | deflection after "
         "the exit, min / max [deg] | residual deflection at t_c [deg] | residual amplitude [deg] | "
         "fence rate at t_c [deg/s] | contact [s] | x_exit [m] |",
         "|---|---|---|---|---|---|---|---|---|---|---|---|---|", *rows, ""]
    if D.damped and b["Psi"] < 0.5 and ("recommended", "small_far") in swing and ("well_damped", "small_far") in swing:
        sr, sd = swing[("recommended", "small_far")], swing[("well_damped", "small_far")]
        L += [f"**The two picks against each other:** the two-case pick {b['B2']:g} / {b['K2']:g} is lower in "
              f"overload than the well-damped {D.damped['B2']:g} / {D.damped['K2']:g} by only "
              f"{(1 - b['worst_overload'] / D.damped['worst_overload']):.1%}, less than the model's own uncertainty "
              f"(k1 and the friction coefficients are assumed, docs/model.md §12), but rings after the impact: "
              f"once small_far "
              f"has left, its deflection swings between {sr[0]:+.1f} and {sr[1]:+.1f} deg and changes sign {sr[2]} times "
              f"before t_c, against {sd[0]:+.1f} to {sd[1]:+.1f} deg and {sd[2]} sign changes for the well-damped pick "
              "(`recommended.png`). Both keep every constraint for both named cases.", ""]
    L += _envelope_pointer(I.res)
    return L


def _envelope_pointer(res: Path) -> list[str]:
    """The picks of this section are the two named loads' choices: say which element is built."""
    from fencesweep.report.analysis import envelope_element

    env = envelope_element(res)
    if not env or "B2" not in env or "K2" not in env:
        return []
    return [f"Both picks are read off the two named loads alone; they are comparisons to the element to build, the "
            f"load envelope's B2 = {env['B2']:g}, K2 = {env['K2']:g} (the opening of this report and section 7, "
            "[`design/recommended.json`](design/recommended.json)), where they are run on the envelope's loads too.", ""]


# ------------------------------------------------------------------ the paper's element, the threshold
def paper_element_section(I: ReportInputs) -> list[str]:
    """The paper's 72/570 against the constraints, the choice against the threshold, the maps' reading."""
    thr = I.residual_max_deg
    rp = {c: I.R[f"{c}_flexible"] for c in CASES}
    res_p = {c: math.degrees(rp[c]["residual_amplitude"]) for c in CASES}
    why = [f"{c}: residual amplitude {res_p[c]:.2f} deg" for c in CASES if res_p[c] > thr]
    other = [f"{c}: {what}" for c in CASES for what, bad in (
        ("not scraped", rp[c]["outcome"] != "scraped"), ("overload > 1", rp[c]["overload"] > 1.0),
        ("deflection_max > dalpha_perm", rp[c]["deflection_max"] > I.T[f"{c}_flexible"].attrs["params"]["dalpha_perm"]))
        if bad]
    L = [f"The paper's element {PAPER_B2:g}/{PAPER_K2:g} (exact run, not a grid cell): overload small_far "
         f"{rp['small_far']['overload']:.3f}, long_near {rp['long_near']['overload']:.3f}; deflection_max "
         f"{math.degrees(rp['small_far']['deflection_max']):.1f} / {math.degrees(rp['long_near']['deflection_max']):.1f} "
         f"deg; residual amplitude {res_p['small_far']:.2f} / {res_p['long_near']:.2f} deg; outcomes "
         f"{rp['small_far']['outcome']} / {rp['long_near']['outcome']}. "
         + ("It keeps every constraint." if not why and not other else
            (f"It fails {'; '.join(other + why)}. " if other else
             f"It fails only the residual-amplitude constraint ({'; '.join(why)}): the paper asks that the fence "
             "start each cycle in its neutral position but gives no number, and with this element the fence still "
             f"swings about its drive with an amplitude of {max(res_p.values()):.2f} deg at t_c; it would pass a "
             f"threshold of {math.ceil(max(res_p.values()) * 2) / 2:g} deg.")),
         "", "How the choice depends on the residual-amplitude threshold (same rule):", "",
         "| residual threshold | feasible cells, both cases | two-case pick B2, K2 | worst overload | well-damped "
         "(0.7 <= Psi <= 1) |", "|---|---|---|---|---|"]
    for t in sorted({0.5, 1.0, 1.5, 2.0, 3.0, thr}):
        Dt = design(I.b2k2, t)
        bb, dd = Dt.best, Dt.damped
        L.append(f"| {t:g} deg | {int(Dt.both.sum())} | "
                 + (f"{bb['B2']:g}, {bb['K2']:g} | {bb['worst_overload']:.3f}" if bb else "none | -") + " | "
                 + (f"{dd['B2']:g}, {dd['K2']:g} ({dd['worst_overload']:.3f})" if dd else "none") + " |")
    return L + [""] + _maps_reading(I, res_p)


def _maps_reading(I: ReportInputs, res_p: dict) -> list[str]:
    D, thr = I.D, I.residual_max_deg
    o_all = D.grids["small_far"]["overload"][D.feasible["small_far"]]
    if not o_all.size:
        return []

    def kmin(b2):
        jj = int(np.argmin(abs(D.B2 - b2)))
        home = np.logical_and.reduce([D.grids[c]["residual_deg"][:, jj] <= thr for c in CASES])
        bad = np.flatnonzero(~home)
        return D.K2[bad[-1] + 1] if len(bad) and bad[-1] + 1 < len(D.K2) else (D.K2[0] if not len(bad) else math.nan)

    kb = {b2: kmin(b2) for b2 in (50.0, 100.0, 200.0)}
    ln = D.grids["long_near"]["overload"]
    ln_binds = int(_failing(D, "long_near", 2, thr).sum())
    same = abs(res_p["small_far"] - res_p["long_near"]) < 0.05
    rigid = I.R["small_far_rigid"]["overload"]
    return [
        f"Reading the maps: over the feasible region the small_far overload only ranges "
        f"{o_all.min():.2f}-{o_all.max():.2f} (the rigid fence: {rigid:.2f}); "
        + ("it is set by the fence's inertia during the few-millisecond impact, not by the element (the paper's own "
           "point, §4.1). " if o_all.max() - o_all.min() < 0.25 * o_all.min() else "the element matters to it. ")
        + "The element decides whether the load is scraped (too soft and too little damped: escaped) and "
        f"whether the fence is home at t_c: the {thr:g} deg boundary needs K2 >= "
        + ", ".join(f"{kb[x]:g} at B2 = {x:g}" for x in kb) + " N m/rad. Those two shape the feasible region; "
        + (f"long_near's overload ({np.nanmin(ln):.2f}-{np.nanmax(ln):.2f} over the grid) never binds. " if not ln_binds
           else f"long_near's overload exceeds 1 in {ln_binds} cells. ")
        + (f"For a well-damped element the residual amplitude at t_c is the same for both loads "
           f"({res_p['small_far']:.2f} / {res_p['long_near']:.2f} deg for {PAPER_B2:g}/{PAPER_K2:g}): it is the "
           "element's lag behind the drive's return stroke, not an after-effect of the load, so it is a property of "
           "B2, K2 and the drive alone." if same else
           f"The residual amplitude of {PAPER_B2:g}/{PAPER_K2:g} differs between the loads ({res_p['small_far']:.2f} / "
           f"{res_p['long_near']:.2f} deg): the load leaves something in the element."), ""]
