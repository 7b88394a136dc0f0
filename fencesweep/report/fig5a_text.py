"""REPORT.md on Fig. 5a beyond its row in section 1: the paper's worst-case arrangement (the worst
over the load's placements), the jumps of our curves, and the escapes, each escape with its cause
read off its row of the table (escape_cause, ESCAPE_CAUSES). No physics, no matplotlib.
"""
from __future__ import annotations

import math

import numpy as np

from fencesweep.report.analysis import (CASES, REAL_IMPACT, STAGE_NAMES, WORST_TABLES, read_traj, traj_path,
                                        worst_over_placements)
from fencesweep.report.inputs import ReportInputs


# ------------------------------------------------------------------ geometry and causes read off a table
def tip_reach_x(l, dP):
    """x of the fence's tip at the moment it has risen to the height of the load's near side (y = dP)."""
    return np.sqrt(np.asarray(l, float) ** 2 - np.asarray(dP, float) ** 2)


def front_at_contact(df):
    """x of the load's leading edge at the first contact: the load rides the belt until then (R_s + v t_A)."""
    return df["R_s"] + df["v"] * df["t_first_contact"]


#: why a load escapes (escape_cause), in words
ESCAPE_CAUSES = {
    "no_contact": "no contact: the load is past the fence before the fence reaches it",
    "rest": "at rest on a free fence: the load lies on the fence from t = 0 at a force of rounding size, no touch "
            "(docs/model.md (11.10)), and that push releases the free fence at once (§3); nothing drives the load on",
    "free": "free fence: released at the first contact, nothing drives the load on (docs/model.md §3: an idealisation "
            "of the impact, not a working drive)",
    "tip": "tip on the face: the load's leading corner is already past the fence's tip when the tip rises to the "
           "load's near side, so the tip strikes that face from below and the blow, along the face's normal, "
           "leaves the load on the belt",
    "at_tip": "corner at the tip: the leading corner meets the fence less than half a load width (A / 2) short of "
              "its tip and slides off it",
    "late": "the stroke is over: the load is still on the fence at the top of the swing (B >= t_c / 2), and the "
            "fence turns back before the load's centroid has reached the far edge",
    "other": "none of the above",
}


def escape_cause(df):
    """For each row of a cycle table: '' when the load is not escaped, else a key of ESCAPE_CAUSES,
    read off the row's results (t_first_contact, contact_time, n_impacts) and start pose."""
    import pandas as pd
    tA = df["t_first_contact"].to_numpy(float)
    xf = front_at_contact(df).to_numpy(float)
    xt = tip_reach_x(df["l"], df["dP"])
    B = tA + df["contact_time"].to_numpy(float)
    untouched = ~np.isfinite(tA) | (df["n_impacts"].to_numpy() == 0)
    free = df["drive"].to_numpy() == "free"
    conds = [df["outcome"].to_numpy() != "escaped", untouched & free & (df["peak_force"].to_numpy(float) > 0),
             untouched, free, xf > xt, xt - xf < df["A"].to_numpy(float) / 2, B >= df["t_c"].to_numpy(float) / 2]
    return pd.Series(np.select(conds, ["", "rest", "no_contact", "free", "tip", "at_tip", "late"], "other"),
                     index=df.index)


def largest_drop(d, axis: str):
    """(a0, a1, o0, o1): the neighbours along `axis` (sorted) between which the overload falls most."""
    d = d.sort_values(axis)
    o = d["overload"].to_numpy()
    k = int(np.argmax(o[:-1] - o[1:]))
    return float(d[axis].iloc[k]), float(d[axis].iloc[k + 1]), float(o[k]), float(o[k + 1])


def _cuts(df, p):
    """The two cuts of Fig. 5a in a table: along v at the working t_c, along t_c at the working v."""
    tc0 = min(set(df["t_c"]), key=lambda x: abs(x - p["t_c"]))
    v0 = min(set(df["v"]), key=lambda x: abs(x - p["v"]))
    return {"v": (df[df["t_c"] == tc0], "t_c", tc0), "t_c": (df[np.isclose(df["v"], v0)], "v", v0)}


# ------------------------------------------------------------------ the section
def fig5a_section(I: ReportInputs) -> list[str]:
    L = ["### Fig. 5a: the paper's worst-case arrangement, the jumps of our curves, the escapes", ""]
    L += _worst_case_text(I)
    L += _jump_text(I)
    L += _escape_text(I)
    return L


def _worst_case_text(I: ReportInputs) -> list[str]:
    import pandas as pd
    if not I.worst:
        return ["(The worst-case tables `fig5a_worst_v.parquet`, `fig5a_worst_tc.parquet` are not there: make them "
                "with `fencesweep grid sweeps/fig5a_worst_v.yaml` and `... fig5a_worst_tc.yaml`.)", ""]
    p = I.base
    all_rows = pd.concat(list(I.worst.values()))
    W = {axis: worst_over_placements(I.worst[n]) for n, axis in WORST_TABLES.items() if n in I.worst}
    named = _cuts(I.f5a[I.f5a["case"] == "small_far"], p)
    wp = next(iter(W.values()))
    wp = wp[np.isclose(wp["t_c"], p["t_c"]) & np.isclose(wp["v"], p["v"])].set_index("drive")
    nv = named["v"][0]
    nv = nv[np.isclose(nv["v"], p["v"])].set_index("drive")
    npl = int(wp["n_placements"].iloc[0]) if len(wp) else 0
    L = [f"**The paper's arrangement.** For Fig. 5a the paper places the load 'so as to contact the fence with that "
         "part which was the most distant one from the fence rotation axis, and the load gravity centre placed on the "
         "impact normal': the worst impact, not one of its two named cases. We search that worst case instead of "
         f"constructing it: the small_far load ({p['L']:g} x {p['A']:g} m, {p['m1']:g} kg) at {npl} start positions "
         f"(dP = {all_rows['dP'].min():g} to {all_rows['dP'].max():g} m from the rail, leading edge R_s = "
         f"{all_rows['R_s'].min():g} to {all_rows['R_s'].max():g} m at activation; tables "
         + ", ".join(f"`{n}.parquet`" for n in I.worst) + "), and take the largest overload over the placements "
         "(Fig. 5a, bottom row)."]
    if len(wp) and len(nv):
        L.append(f"At the working point (t_c = {p['t_c']:g} s, v = {p['v']:g} m/s) the named small_far gives "
                 + " / ".join(f"{nv.loc[d, 'overload']:.3f}" for d in ("rigid", "flexible", "free"))
                 + " (rigid / flexible / free), the worst placement "
                 + " / ".join(f"{wp.loc[d, 'overload']:.3f} (dP = {wp.loc[d, 'dP']:g}, R_s = {wp.loc[d, 'R_s']:.2g} m)"
                              for d in ("rigid", "flexible", "free")) + ".")
    for axis, w in W.items():
        piv = w.pivot_table(index=axis, columns="drive", values="overload")
        real = piv["free"] >= REAL_IMPACT
        r = (piv["flexible"] / piv["free"])[real]
        over = {d: piv.index[piv[d] > 1].tolist() for d in ("rigid", "flexible", "free")}
        L.append(f"Along {axis} ({len(piv)} values): worst-case flexible / free = {r.min():.2f} to {r.max():.2f} "
                 f"where the free fence's worst overload is >= {REAL_IMPACT:g}; a worst overload above 1 at "
                 + "; ".join(f"{d}: " + (", ".join(f"{x:g}" for x in over[d]) if over[d] else "none")
                             for d in over) + ".")
    two = pd.concat(list(W.values()))
    two_r = two[two["drive"] == "rigid"]
    L.append(f"Of the worst placements, {int(two['two_points'].sum())} of {len(two)} ({int(two_r['two_points'].sum())} "
             f"of {len(two_r)} for the rigid fence) had two fence contact points at once (S3) during their contact; "
             "peak_force (docs/model.md §11) adds the forces of all contact points." + _worst_peak_stage(I))
    L.append("")
    return L


def _worst_peak_stage(I: ReportInputs) -> str:
    """Where the worst placements at the working point peak (trajectories traj/worst_<drive>.parquet)."""
    peaks = {}
    for drive in ("rigid", "flexible", "free"):
        if traj_path(I.res, f"worst_{drive}").exists():
            df = read_traj(I.res, f"worst_{drive}")
            k = int(np.argmax(df["N_fence"].to_numpy()))
            peaks[drive] = (int(df["stage"].iloc[k]), float(df["t"].iloc[k]), df.attrs["params"],
                            _corner_along(df.iloc[k], df.attrs["params"]))
    if not peaks:
        return ""
    txt = (" At the working point (trajectories `traj/worst_<drive>.parquet`) the worst placements peak in stage "
           + ", ".join(f"{STAGE_NAMES.get(st, st)} ({d}, dP = {p['dP']:g}, R_s = {p['R_s']:.2g} m, t = {t:.4f} s, "
                       f"the load's corner on the fence {s_:.3f} m along it, l = {p['l']:g} m)"
                       for d, (st, t, p, s_) in peaks.items()) + ".")
    two = [d for d, (st, _, p, s_) in peaks.items() if st == 2 and abs(s_ - p["l"]) < p["A"] / 2]
    if two:
        txt += (f" A peak in S3 with that corner at the fence's tip ({', '.join(two)}): two points of one contact "
                "manifold (docs/model.md §5.2), the face's corner and the load's edge under the tip; the fence "
                "meets the load through one manifold, so a corner and the tip no longer both push for one overlap "
                "(results/tip.md: the double count that raised the tip band's peaks up to 2x is gone).")
    return txt


def _corner_along(row, p) -> float:
    """How far along the fence (from the pivot) the load's corner nearest the fence's line (the one
    pressing on it) is, in one trajectory row."""
    from fencesweep.model.params import load_corners

    d = (math.cos(row["alpha"]), math.sin(row["alpha"]))
    pts = [(row["x"] + cx, row["y"] + cy) for cx, cy in load_corners(p["L"], p["A"], row["phi"])]
    x, y = min(pts, key=lambda q: -q[0] * d[1] + q[1] * d[0])  # the smallest distance along the normal n
    return x * d[0] + y * d[1]


def _jump_text(I: ReportInputs) -> list[str]:
    p = I.base
    need = {"R_s", "dP", "l", "t_first_contact"}
    sf = I.f5a[I.f5a["case"] == "small_far"]
    if not need <= set(sf.columns):
        return []
    L = ["**The jumps of the named case's curves.**"]
    for axis, (d, fixed, fval) in _cuts(sf, p).items():
        rig = d[d["drive"] == "rigid"]
        a0, a1, o0, o1 = largest_drop(rig, axis)
        both = rig[rig[axis].isin([a0, a1])].sort_values(axis)
        xf = front_at_contact(both).to_numpy()
        xt = float(tip_reach_x(both["l"].iloc[0], both["dP"].iloc[0]))
        after = rig[rig[axis] >= a1]
        after = after[np.isfinite(after["t_first_contact"])]
        others = "; ".join(f"{dr} {o0_:.3f} -> {o1_:.3f}" for dr in ("flexible", "free")
                           for _, _, o0_, o1_ in [largest_drop(d[d["drive"] == dr], axis)]
                           if largest_drop(d[d["drive"] == dr], axis)[:2] == (a0, a1))
        unit = "m/s" if axis == "v" else "s"
        explained = xf[0] <= xt < xf[1]
        L.append(f"Along {axis} (at {fixed} = {fval:g}): the rigid fence's overload falls from {o0:.3f} at {axis} = "
                 f"{a0:g} to {o1:.3f} at {a1:g} {unit}" + (f" ({others} at the same step)" if others else "") + ". "
                 + (f"The load rides the belt until the first contact, so its leading corner is then at x = R_s + "
                    f"v t_A = {xf[0]:.3f} m before the step and {xf[1]:.3f} m after it; the fence's tip rises to the "
                    f"height of the load's near side (y = dP = {both['dP'].iloc[0]:g} m) at x = sqrt(l^2 - dP^2) = "
                    f"{xt:.3f} m. Before the step the corner is short of the tip and the fence's face strikes it: "
                    "the belt's speed adds its component along the fence's normal (v sin alpha) to the fence's own. "
                    "After it the corner is already past the tip, and the tip strikes the load's flat near face from "
                    "below, along the face's normal, to which the belt's speed adds nothing; the first contact is "
                    f"then the moment the tip reaches y = dP, t_A = {_span(after['t_first_contact'], '.4f')} s "
                    f"for every {axis} from {a1:g} {unit} on."
                    if explained else
                    f"The leading corner's x at the first contact ({xf[0]:.3f} / {xf[1]:.3f} m) does not cross the "
                    f"tip's x at the load's height ({xt:.3f} m) here: this jump has another cause."))
    L.append("")
    return L


def _span(x, fmt: str) -> str:
    """'0.4277' when all values print alike, else '0.5346 to 0.5975'."""
    lo, hi = format(float(x.min()), fmt), format(float(x.max()), fmt)
    return lo if lo == hi else f"{lo} to {hi}"


def _nearest_escapes(I: ReportInputs) -> str:
    """The escapes of the named cases (rigid and flexible fence) nearest the working point, along each cut."""
    p = I.base
    out = []
    for case in CASES:
        dc = I.f5a[I.f5a["case"] == case]
        for axis, (d, _, _) in _cuts(dc, p).items():
            for drive in ("rigid", "flexible"):
                g = d[d["drive"] == drive]
                esc = g[escape_cause(g) != ""]
                lo, hi = esc[esc[axis] < p[axis]][axis], esc[esc[axis] > p[axis]][axis]
                side = ([f"{axis} <= {lo.max():g}"] if len(lo) else []) + ([f"{axis} >= {hi.min():g}"] if len(hi) else [])
                if side:
                    out.append(f"{case} {drive}: {' and '.join(side)}")
    return ("Nearest the working point (v = {:g} m/s, t_c = {:g} s), the named cases escape at ".format(p["v"], p["t_c"])
            + "; ".join(out) + " (the escape at the working point itself: "
            + ("none" if not _escapes_at_working_point(I) else ", ".join(_escapes_at_working_point(I))) + ").")


def _escapes_at_working_point(I: ReportInputs) -> list:
    p = I.base
    d = I.f5a[np.isclose(I.f5a["v"], p["v"]) & np.isclose(I.f5a["t_c"], p["t_c"]) & (I.f5a["drive"] != "free")]
    return [f"{r.case} {r.drive}" for r in d[d["outcome"] == "escaped"].itertuples()]


def _runs_text(vals) -> str:
    """'1, 1.1, 1.2' -> '1-1.2' for consecutive grid values, joined by commas."""
    vals = sorted(vals)
    return ", ".join(f"{v:g}" for v in vals) if len(vals) <= 3 else f"{vals[0]:g}-{vals[-1]:g} ({len(vals)} values)"


def _escape_text(I: ReportInputs) -> list[str]:
    p = I.base
    need = {"R_s", "dP", "l", "A", "t_first_contact", "contact_time", "n_impacts"}
    if not need <= set(I.f5a.columns):
        return []
    L = ["**The escapes** (x in Fig. 5a) along the two cuts, each with its cause read off the row (first contact, "
         "contact time, start pose):", "", "| case | drive | along | escaped | cause: where |", "|---|---|---|---|---|"]
    seen = set()
    for case in CASES:
        dc = I.f5a[I.f5a["case"] == case]
        for axis, (d, fixed, fval) in _cuts(dc, p).items():
            for drive in ("rigid", "flexible", "free"):
                g = d[d["drive"] == drive]
                cause = escape_cause(g)
                esc = g[cause != ""]
                if not len(esc):
                    continue
                parts = []
                for c in ESCAPE_CAUSES:
                    where = esc[cause[esc.index] == c][axis]
                    if len(where):
                        seen.add(c)
                        parts.append(f"{c}: {_runs_text(where.tolist())}")
                L.append(f"| {case} | {drive} | {axis} (at {fixed} = {fval:g}) | {len(esc)} of {len(g)} | "
                         + "; ".join(parts) + " |")
    L += ["", "Causes: " + "; ".join(f"**{c}**: {ESCAPE_CAUSES[c]}" for c in ESCAPE_CAUSES if c in seen) + ".", "",
          _nearest_escapes(I), ""]
    return L
