"""REPORT.md, the paper's results beside ours: section 1's table (Psi, Figs 2-3, 5b, 5a, 6, 7-8),
the stage sequences of the named cases, and section 4, where our numbers differ from the paper's
and why. Every number is read off the ReportInputs (no physics, no matplotlib).
"""
from __future__ import annotations

import math

import numpy as np

from fencesweep.report.analysis import (CASES, MIN_STAGE, MODEL_5B, PAPER_5B, PAPER_B2, PAPER_FREE_H, PAPER_K2,
                                        REAL_IMPACT, RISE_SAMPLES, SLIGHT, STAGE_NAMES, events, first_impact,
                                        pulse_duration, worst_over_placements)
from fencesweep.report.inputs import ReportInputs


# ------------------------------------------------------------------ drop heights (freefall_H table)
def _interp_height(ff, peak):
    """Drop height whose free-fall peak equals `peak` (freefall_H table, monotone in H)."""
    d = ff.sort_values("H")
    return float(np.interp(peak, d["peak_force"].to_numpy(), d["H"].to_numpy(), left=np.nan, right=np.nan))


def _peak_at(ff, H):
    """Free-fall peak force at drop height H (freefall_H table)."""
    d = ff.sort_values("H")
    return float(np.interp(H, d["H"].to_numpy(), d["peak_force"].to_numpy()))


# ------------------------------------------------------------------ 1. the paper's results
def paper_section(I: ReportInputs) -> list[str]:
    rows = (_row_psi, _row_impacts, _row_fig5b, _row_fig5a, _row_fig6, _row_cycles)
    return (["## 1. The paper's results (docs/model.md §13), ours beside them", "",
             "| # | paper | ours | difference |",
             "|---|---|---|---|"] + [f"| {k} | {row(I)} |" for k, row in enumerate(rows, 1)] + [""])


def _row_psi(I: ReportInputs) -> str:
    from fencesweep.model import params as P

    pf = I.base
    psi0 = P.relative_damping(pf["B2"], pf["K2"], pf["I2"])
    return (f"Psi = B2 / (2 sqrt(K2 I2)) ~ 1 for {PAPER_B2:g} / {PAPER_K2:g}, m2 = {pf['m2']:g} kg, l = {pf['l']:g} m "
            f"(§4.2) | Psi = {psi0:.3f} (I2 = m2 l^2/3 = {pf['I2']:.2f} kg m^2) | "
            + ("none: 'about 1' is the paper's rounding" if abs(psi0 - 1) < 0.05 else f"{psi0 - 1:+.2f} from 1"))


def _first_impacts(I: ReportInputs) -> dict:
    """(law, drive) -> first_impact of small_far, over 1.5 pulse durations of the rigid fence's impact."""
    imp = {}
    for law, suf in (("linear", "_linear"), ("hertz", "")):
        win = 1.5 * pulse_duration(I.T[f"small_far_rigid{suf}"])
        for drv in ("rigid", "flexible", "free"):
            imp[(law, drv)] = first_impact(I.T[f"small_far_{drv}{suf}"], win)
    return imp


def _row_impacts(I: ReportInputs) -> str:
    imp = _first_impacts(I)
    lin = {d: imp[("linear", d)] for d in ("rigid", "flexible", "free")}
    hz = {d: imp[("hertz", d)] for d in ("rigid", "flexible", "free")}
    spread_lin = (max(v["peak"] for v in lin.values()) - min(v["peak"] for v in lin.values())) / lin["rigid"]["peak"]
    drop_hz = 1 - min(hz["flexible"]["peak"], hz["free"]["peak"]) / hz["rigid"]["peak"]

    def frac_at(name, law, dt):
        df = I.T[name]
        t, n = df["t"].to_numpy(), df["N_fence"].to_numpy()
        a = events(df).A
        sel = t >= a
        return float(np.interp(a + dt, t[sel], n[sel])) / imp[(law, name.split("_")[2])]["peak"]

    def rate_at_contact(name):
        """The fence's rate at the first contact A (the trajectory has a row at every event)."""
        df = I.T[name]
        return math.degrees(float(np.interp(events(df).A, df["t"].to_numpy(), df["alpha_dot"].to_numpy())))

    d0, d1 = RISE_SAMPLES
    rate_f, rate_r = rate_at_contact("small_far_flexible_linear"), rate_at_contact("small_far_rigid_linear")
    f_lin = frac_at("small_far_rigid_linear", "linear", d0)
    f_hz, f_hz1 = frac_at("small_far_rigid", "hertz", d0), frac_at("small_far_rigid", "hertz", d1)
    e = I.base["e"]
    ok = spread_lin < 0.1 and drop_hz > 0.2
    return (
        "Figs 2-3: with the linear Kelvin law the force jumps to a non-zero value at contact and its peak "
        "barely depends on the fence (rigid / flexible / free); with the modified law it starts from 0 and the "
        "fence matters | first impact of small_far in the cycle (rigid fence). Linear law: at contact the force "
        f"jumps to b D' = {lin['rigid']['N_onset'] / 1e3:.2f} kN, {f_lin:.0%} of its peak "
        f"{d0 * 1e3:g} ms later; peaks rigid / flexible / free {lin['rigid']['peak'] / 1e3:.2f} / "
        f"{lin['flexible']['peak'] / 1e3:.2f} / {lin['free']['peak'] / 1e3:.2f} kN (spread {spread_lin:.0%}). "
        f"Modified law: 0 at contact, rising like (t - t_A)^(1/4) ({f_hz:.0%} of the peak after {d0 * 1e3:g} ms, "
        f"{f_hz1:.0%} after {d1 * 1e3:g} ms); peaks {hz['rigid']['peak'] / 1e3:.2f} / {hz['flexible']['peak'] / 1e3:.2f} / "
        f"{hz['free']['peak'] / 1e3:.2f} kN (flexible and free {drop_hz:.0%} or more below rigid) | "
        + (("reproduced. The curves are cut from cycle trajectories (the first impact of small_far, zoomed), not "
            "from an impact-only scene, and that impact is oblique, so the values are not the paper's. "
            + (f"Our linear-law rigid and free peaks coincide: with e = {e:g} the peak is the jump b D' at contact, "
               "which no fence mass can change; " if abs(lin["rigid"]["peak"] - lin["free"]["peak"])
               < 1e-3 * lin["rigid"]["peak"] else "")
            + "the flexible fence's is "
            + (f"a little higher because at contact it turns faster than its drive ({rate_f:.0f} against "
               f"{rate_r:.0f} deg/s)" if rate_f > rate_r else
               f"different although at contact it turns no faster than its drive ({rate_f:.0f} against "
               f"{rate_r:.0f} deg/s): its own approach to the load differs"))
           if ok else "see Figs 2-3: the pattern is not cleanly reproduced at these settings"))


def _quotient_5b(I: ReportInputs):
    p5 = I.f5b.pivot_table(index="m2", columns="drive", values="peak_force")
    q = p5["rigid"] / p5["free"]
    qf = (p5["rigid"] / p5["flexible"]) if "flexible" in p5 else None

    def qat(m):
        return float(q.loc[m]) if m in q.index else float(np.interp(math.log(m), np.log(q.index), q.values))
    return p5, qat, qf


def _row_fig5b(I: ReportInputs) -> str:
    _, qat, qf = _quotient_5b(I)
    m0, (m_lo, m_hi) = 5.0, (min(MODEL_5B), max(MODEL_5B))
    return (f"Fig. 5b: peak force against a rigid fence over that against a free fence of mass m2 (point load at "
            f"R = {I.base['l']:g} m, m1 = {I.base['m1']:g} kg, w = {I.base['v']:g} m/s): ~ {PAPER_5B:g} at m2 = "
            f"{m0:g} kg, growing as m2 falls | {qat(m0):.3f} at {m0:g} kg ({qat(m_lo):.2f} at {m_lo:g} kg, "
            f"{qat(m_hi):.2f} at {m_hi:g} kg; docs/model.md §13.3 expects "
            + ", ".join(f"{MODEL_5B[m]:.2f}" for m in (m0, m_lo, m_hi)) + ")"
            + (f"; the flexible {PAPER_B2:g}/{PAPER_K2:g} fence gives {float(qf.loc[m0]):.3f} at {m0:g} kg, the "
               "element is invisible here: the peak comes before the element's torque has built up"
               if qf is not None and m0 in qf.index else "")
            + " | " + (f"none beyond the paper's rounding ({PAPER_5B:g})" if abs(qat(m0) - MODEL_5B[m0]) < 0.02 else
                       f"ours differs from {MODEL_5B[m0]:.2f} by {qat(m0) - MODEL_5B[m0]:+.3f}"))


def _fig5a_numbers(I: ReportInputs) -> dict:
    """The working-point cut of Fig. 5a (small_far, t_c nearest the working point) and its drop heights."""
    p = I.base
    sf = I.f5a[I.f5a["case"] == "small_far"]
    tc0 = min(set(sf["t_c"]), key=lambda x: abs(x - p["t_c"]))
    at = sf[sf["t_c"] == tc0].pivot_table(index="v", columns="drive", values="overload")
    pk = sf[sf["t_c"] == tc0].pivot_table(index="v", columns="drive", values="peak_force")
    v2 = min(at.index, key=lambda x: abs(x - p["v"]))
    h_free = [_interp_height(I.ffh, x) for x in pk["free"]]
    touched = (at["free"] > 0.05).to_numpy()  # the free fence touches the load at all
    return dict(tc0=tc0, at=at, pk=pk, v2=v2, r_fl=at["flexible"] / at["free"], real=at["free"] >= REAL_IMPACT,
                h2_free=_interp_height(I.ffh, float(pk.loc[v2, "free"])),
                h2_flex=_interp_height(I.ffh, float(pk.loc[v2, "flexible"])),
                h_sel=[h for h, ok in zip(h_free, touched) if ok], v_sel=at.index[touched])


def _row_fig5a(I: ReportInputs) -> str:
    F = _fig5a_numbers(I)
    at, r_fl, real, v2, h_sel = F["at"], F["r_fl"], F["real"], F["v2"], F["h_sel"]
    o2 = at.loc[v2]
    return (
        f"Fig. 5a: the flexible element {PAPER_B2:g}/{PAPER_K2:g} gives only slightly more overload than the free "
        f"fence; the free fence brings the overload down to that of a drop from about H = {PAPER_FREE_H:g} m (§4.1) | "
        f"small_far at t_c = {F['tc0']:g} s, v = {v2:g} m/s: overload rigid {o2['rigid']:.3f}, flexible "
        f"{o2['flexible']:.3f}, free {o2['free']:.3f} (flexible / free = {r_fl.loc[v2]:.3f}); flexible / free = "
        f"{r_fl[real].min():.2f} to {r_fl[real].max():.2f} for every v with a real impact (free overload >= "
        f"{REAL_IMPACT:g}: v = {at.index[real].min():g} to {at.index[real].max():g} m/s), {r_fl.max():.2f} at most (at "
        f"v = {r_fl.idxmax():g} m/s, overloads {at.loc[r_fl.idxmax(), 'flexible']:.2f} / "
        f"{at.loc[r_fl.idxmax(), 'free']:.2f}). The free fence's peak equals a drop from H = {F['h2_free']:.2f} m at "
        f"v = {v2:g} m/s (flexible {F['h2_flex']:.2f} m) and {np.nanmin(h_sel):.2f} to {np.nanmax(h_sel):.2f} m "
        f"(median {np.nanmedian(h_sel):.2f} m) over the v range. The paper's own arrangement (the worst placement "
        "of the load) and the jumps and escapes of these curves: below the stage sequences | "
        + (f"reproduced for the named case: the flexible fence stays within {(r_fl[real].max() - 1):.0%} of the free "
           "one wherever the impact is substantial"
           + ("; it is relatively worse only at the slowest belt, where every overload is small"
              if r_fl.idxmax() == at.index.min() else "")
           + f". The drop height of the free fence over the v range is {np.nanmin(h_sel):.2f}-{np.nanmax(h_sel):.2f} m "
           f"against the paper's 'about {PAPER_FREE_H:g} m'; at the working point itself it is {F['h2_free']:.2f} m, "
           f"{F['pk'].loc[v2, 'free'] / _peak_at(I.ffh, PAPER_FREE_H) - 1:+.0%} force against a drop from "
           f"{PAPER_FREE_H:g} m" if r_fl[real].max() < 1 + SLIGHT else
           f"the flexible fence is more than {SLIGHT:.0%} above the free one somewhere with a real impact")
        + _worst_free_height(I))


def _worst_free_height(I: ReportInputs) -> str:
    """The free fence's overload in the worst-case arrangement, as drop heights (Fig. 5a row)."""
    import pandas as pd
    if not I.worst:
        return ""
    w = pd.concat([worst_over_placements(t) for t in I.worst.values()])
    w = w[w["drive"] == "free"]
    h = [_interp_height(I.ffh, x) for x in w["peak_force"]]
    return (f". In the paper's worst-case arrangement (below) the free fence's overload is {w['overload'].min():.2f}-"
            f"{w['overload'].max():.2f} over both cuts, a drop from H = {np.nanmin(h):.2f}-{np.nanmax(h):.2f} m")


def _trend(s) -> str:
    """How a curve over B2 goes: 'rises', 'falls', a plateau, or not monotonically."""
    y = s.to_numpy()
    k = int(np.argmax(y))
    if y[-1] >= y[0]:
        if k < len(y) - 1 and (y[k] - y[-1]) < 0.05 * y[k]:
            return f"rises to a plateau of {y[k]:.1f} near B2 = {s.index[k]:g}"
        return "rises" if (np.diff(y) >= 0).mean() > 0.8 else "rises, not monotonically"
    return "falls" if (np.diff(y) <= 0).mean() > 0.8 else "falls, not monotonically"


def _row_fig6(I: ReportInputs) -> str:
    psi = I.psi
    pv = psi.pivot_table(index="B2", columns="case", values=["damper_energy", "deflection_max"])
    outc = psi.pivot(index="B2", columns="case", values="outcome")
    E, Dm = pv["damper_energy"], pv["deflection_max"]
    cases = [c for c in CASES if c in E]
    bmin = {c: float(outc.index[(outc[c] == "scraped").to_numpy()].min()) if (outc[c] == "scraped").any()
            else math.nan for c in outc.columns}
    e_txt = "; ".join(f"{c}: {E[c].iloc[0]:.1f} J at B2 = {pv.index[0]:g}, {E[c].iloc[-1]:.1f} J at "
                      f"{pv.index[-1]:g} ({_trend(E[c])})" for c in cases)
    d_txt = "; ".join(f"{c}: {math.degrees(Dm[c].iloc[0]):.1f} deg to {math.degrees(Dm[c].iloc[-1]):.1f} deg "
                      f"({_trend(Dm[c])})" for c in cases)
    p = I.base
    ke = 0.5 * p["m1"] * p["v"] ** 2  # the load's kinetic energy on the belt
    falls = {c: E[c].iloc[-1] < E[c].iloc[0] for c in cases}   # the paper's trend: lower B2, more energy
    defl_ok = all(Dm[c].iloc[-1] < Dm[c].iloc[0] for c in cases)
    energy = ("the energy trend is the paper's for both loads (the damper energy falls as B2 grows)" if all(falls.values())
              else "the energy trend depends on the load: " + "; ".join(
                  f"for {c} the damper energy {'falls' if falls[c] else 'rises'} as B2 grows, to at most "
                  f"{E[c].max():.1f} J, {E[c].max() / ke:.0%} of the load's kinetic energy 1/2 m1 v^2 = {ke:.1f} J"
                  + ("" if falls[c] else " (a stiff, strongly damped element takes up the impact)")
                  for c in cases) + ". The paper does not say which load its Fig. 6 shows")
    return (f"Fig. 6 (Psi = 1): 'because of the level of energy dissipation (Fig. 6a) possibly the lowest values "
            f"of B2 should be chosen'; 'smaller values of B2 result in bigger relative fence deflections' (Fig. 6b), "
            f"so B2 is set by the permitted deflection | damper energy {e_txt}. Maximal deflection {d_txt}. At "
            f"Psi = 1 both loads are scraped only from B2 = {max(bmin.values()):g} N m s/rad up (small_far from "
            f"{bmin.get('small_far', math.nan):g}, long_near from {bmin.get('long_near', math.nan):g}) | "
            + ("the deflection trend is reproduced" if defl_ok else "the deflection trend is NOT reproduced")
            + f"; {energy}.")


def _s3_starts(I: ReportInputs) -> tuple[float, float]:
    """Start of long_near's first S3, flexible and rigid fence (Fig. 7b's Delta t1)."""
    def s3(ev):
        return next((t0 for t0, _, s in ev.runs if s == 2), math.nan)
    return s3(events(I.T["long_near_flexible"])), s3(events(I.T["long_near_rigid"]))


def _row_cycles(I: ReportInputs) -> str:
    R = I.R
    rows = [f"{c}: rigid {R[f'{c}_rigid']['outcome']}, flexible {R[f'{c}_flexible']['outcome']}; contact "
            f"{R[f'{c}_rigid']['contact_time']:.3f} s -> {R[f'{c}_flexible']['contact_time']:.3f} s; exit at "
            f"x = {R[f'{c}_rigid']['x_exit']:.3f} m -> {R[f'{c}_flexible']['x_exit']:.3f} m" for c in CASES]
    ok6 = all(R[f"{c}_{d}"]["outcome"] == "scraped" for c in CASES for d in ("rigid", "flexible"))
    longer = all(R[f"{c}_flexible"]["contact_time"] > R[f"{c}_rigid"]["contact_time"] for c in CASES)
    further = all(R[f"{c}_flexible"]["x_exit"] > R[f"{c}_rigid"]["x_exit"] for c in CASES)
    s3_f, s3_r = _s3_starts(I)
    dt1 = s3_r - s3_f
    p = I.T["long_near_rigid"].attrs["params"]
    return (f"§4.2, Figs 7-8: both unfavourable loads are scraped at t_c = {p['t_c']:g} s, v = {p['v']:g} m/s, "
            f"R_s = {p['R_s']:g} with the rigid and with the flexible fence; with the flexible fence the contact "
            "lasts longer and the load travels further along the belt before it leaves | " + "; ".join(rows) + " | "
            + ("reproduced" if ok6 and longer and further else "NOT fully reproduced (see the numbers)")
            + (". One detail is not: the paper's Fig. 7b has the flexible fence bring long_near into S3 earlier "
               f"(its Delta t1); ours starts S3 at {s3_f:.4f} s (flexible) and {s3_r:.4f} s (rigid), "
               f"{abs(dt1) * 1e3:.1f} ms {'later' if dt1 < 0 else 'earlier'} with the flexible fence: in our model S4 "
               f"ends when the load's rear corner passes the pivot and leaves the rail, at L / v = "
               f"{p['L'] / p['v']:.2f} s whatever the fence does." if dt1 < 1e-3 else
               f". As in the paper's Fig. 7b the flexible fence brings long_near into S3 earlier, by "
               f"{dt1 * 1e3:.1f} ms."))


# ------------------------------------------------------------------ stage sequences
def _seq(ev) -> str:
    return " -> ".join(f"{STAGE_NAMES[s]} ({(t1 - t0) * 1e3:.0f} ms)" for t0, t1, s in ev.runs)


def stage_section(I: ReportInputs) -> list[str]:
    L = [f"Stage sequences (docs/model.md §10; runs shorter than {MIN_STAGE * 1e3:g} ms merged), rigid and flexible "
         f"{PAPER_B2:g}/{PAPER_K2:g} fence:", ""]
    ev = {(c, d): events(I.T[f"{c}_{d}"], MIN_STAGE) for c in CASES for d in ("rigid", "flexible")}
    for (c, d), e in ev.items():
        L.append(f"* {c}, {d}: {' -> '.join(f'{STAGE_NAMES[s]} ({t1 - t0:.3f} s)' for t0, t1, s in e.runs)}; "
                 f"A = {e.A:.3f} s, B = {e.B:.3f} s")
    p = I.T["small_far_flexible"].attrs["params"]
    flush = {d: any(s == 2 for _, _, s in ev[("small_far", d)].runs) for d in ("rigid", "flexible")}
    gap = p["P_max"] - (p["dP"] + p["A"] / 2)
    ln = [s for _, _, s in ev[("long_near", "flexible")].runs]
    s4_then_s3 = 3 in ln and 2 in ln and ln.index(3) < ln.index(2)
    L += ["", "The paper's Fig. 4b has the far load go S1 (impact, the corner brushing along the fence) then S3 (the "
          f"load flush on the fence, sliding along it). Ours, flexible fence: {_seq(ev[('small_far', 'flexible')])}; "
          f"rigid fence: {_seq(ev[('small_far', 'rigid')])}"
          + (", never lying flush (no S3)" if not any(flush.values()) else "")
          + f". The {p['L']:g} x {p['A']:g} m load starts with its centroid {gap:.2f} m from the far edge "
          f"(dP = {p['dP']:g} m)" + (", so it is scraped before it can swing flush." if not any(flush.values()) else ".")
          + (" Its Fig. 4c (long load at the rail: S4, then S3) is what we get." if s4_then_s3 else
             f" Its Fig. 4c (long load at the rail: S4, then S3) is not what we get: {_seq(ev[('long_near', 'flexible')])}."),
          ""]
    return L


# ------------------------------------------------------------------ 4. where we differ
def differences_section(I: ReportInputs) -> list[str]:
    F = _fig5a_numbers(I)
    p5, _, _ = _quotient_5b(I)
    h_sel = F["h_sel"]
    s3_f, s3_r = _s3_starts(I)
    dt1 = s3_r - s3_f
    pl = I.T["long_near_rigid"].attrs["params"]
    ps = I.T["small_far_flexible"].attrs["params"]
    gap = ps["P_max"] - (ps["dP"] + ps["A"] / 2)
    E = I.psi.pivot_table(index="B2", columns="case", values="damper_energy")
    way = {c: ("rises" if E[c].iloc[-1] > E[c].iloc[0] else "falls") for c in CASES if c in E}
    s1 = sum(1 for _, _, s in events(I.T["small_far_flexible"], MIN_STAGE).runs if s == 0)
    w_pt = 5.0 if 5.0 in p5.index else None
    return [
        "## 4. Where our numbers differ from the paper's, and why", "",
        "* **Figs 2-3 are cut from cycle runs, not from an impact-only scene.** The impact of small_far in the "
        "cycle is oblique (the load's corner strikes the fence near its tip while the load turns), so peak values "
        "and durations are not the paper's centred point impact; the qualitative points (jump at contact with the "
        "linear law, no fence effect on its peak; zero start and a clear fence effect with the modified law) are "
        "what we compare.",
        f"* **Equivalent drop height of the free fence.** The paper: about H = {PAPER_FREE_H:g} m over the examined "
        f"t_c and v. Ours (small_far, t_c = {F['tc0']:g} s): {F['h2_free']:.2f} m at v = {F['v2']:g} m/s, "
        f"{np.nanmin(h_sel):.2f}-{np.nanmax(h_sel):.2f} m (median {np.nanmedian(h_sel):.2f} m) over v = "
        f"{F['v_sel'].min():g}-{F['v_sel'].max():g} m/s"
        + (f"; the point impact of Fig. 5b (m2 = {w_pt:g} kg) gives "
           f"{_interp_height(I.ffh, float(p5['free'].loc[w_pt])):.2f} m" if w_pt else "")
        + ". The cycle's impact is oblique (the corner strikes near the fence tip while the load turns) and k1, the "
        "swing and the friction are ours, not the paper's.",
        "* **Fig. 6 damper energy.** Our damper energy at Psi = 1 "
        + " and ".join(f"{w} with B2 for {c}" for c, w in way.items())
        + "; the paper's text implies one trend (lower B2, more energy absorbed) without saying which load the figure "
        "shows.",
        f"* **Fig. 7b, Delta t1.** The paper's flexible fence brings long_near into S3 earlier; in ours S4 -> S3 "
        f"comes {abs(dt1) * 1e3:.1f} ms {'later' if dt1 < 0 else 'earlier'}"
        + (f", i.e. at the same time: our S4 ends when the load's rear corner passes the pivot and leaves the rail, "
           f"which the belt fixes (L / v = {pl['L'] / pl['v']:.2f} s). " if abs(dt1) < 5e-3 else ". ")
        + "The paper's S4 is modelled with bilateral constraints (its eqs. 16-18), ours with contacts; its S4 -> S3 "
        "criterion is not stated.",
        "* **Fig. 4b, stage sequence of the far load.** The paper's far load slides along the fence (S3) after the "
        + ("impact; ours never lies flush: it is scraped (centroid at the far edge) after "
           f"{s1} S1 contact{'s' if s1 != 1 else ''}, because with dP = {ps['dP']:g} m its centroid starts only "
           f"{gap:.2f} m from the edge." if not any(s == 2 for _, _, s in events(I.T['small_far_flexible']).runs)
           else "impact; ours does too (see the stage sequences)."),
        f"* **Parameters the paper does not give** (docs/model.md §12 fixes them): k1 = {ps['k1']:.1e} N/m^1.5, "
        f"mu1 = {ps['mu1']:g}, mu2 = {ps['mu2']:g}, the drive swing {math.degrees(ps['swing']):.3g} deg, dalpha_perm = "
        f"{math.degrees(ps['dalpha_perm']):.3g} deg. The absolute forces and overloads depend on k1 and the swing; the "
        "ratios (Fig. 5b) do not depend on k1.", ""]
