"""Find the grazing scenes of the validation set with the reference (never the engine).

    python tests/reference/find_grazes.py                   # all grazes
    python tests/reference/find_grazes.py --only tip_edge

For each contact kind of docs/model.md §5 -- corner-fence ("fence"), tip-edge ("tip"),
corner-rail ("rail") -- and for a tip clipping a corner (tip and corner together),
one scene parameter is bisected between a value at which the
reference sees a contact of that kind and one at which it does not
(model.contact_diagnostics: touch_<kind>).  The signed clearance
c = min_gap_<kind> - max_pen_<kind> (the closest approach, negative = the deepest
penetration) is smooth in the parameter on either side of the transition, so secant
steps from the bisection's runs on the touching side reach a penetration of about
TARGET (the graze) and on the missing side a gap of about TARGET (the near miss); each
value is rounded to a few decimals before it is run.  The script prints the bracket,
both values, their penetration or gap, and the same at rtol RTOL_CHECK, to show that
the reference's own error is far below the depth (a graze the reference cannot tell
from a miss is no test).

It writes nothing: the values go into tests/reference/scenes.yaml by hand, with
a comment that says how they were found.
"""
from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # tests/: the package `reference`

from reference import model  # noqa: E402

RTOL = 1e-10            # the reference's tolerance for the CSV
RTOL_CHECK = 1e-11      # a second, tighter run of the chosen values
TARGET = 2e-5           # [m] wanted penetration of the graze and gap of the near miss
WINDOW = (5e-6, 5e-5)   # [m] accepted range of both
BRACKET_C = 2e-7        # [m] bisect until |c| at both ends of the bracket is below this
MAX_SECANT = 6          # secant steps towards each target

#: name -> (contact kind, scene without the parameter, parameter, a touching value, a
#: missing value, what happens).  The scenes are graze_<name> and miss_<name>.
GRAZES = {
    "corner_fence": (
        "fence",
        {"L": 0.3, "A": 0.1, "dP": 0.2, "v": 0.5, "t_c": 0.9, "drive": "rigid"},
        "R_s", 0.0, -0.05,
        "a slow load reaches the rigid fence at the top of its swing; its front-bottom "
        "corner meets the face as the fence turns back (the face recedes faster than "
        "the load follows it)"),
    "tip_edge": (
        "tip",
        {"L": 0.3, "A": 0.1, "P_max": 1.0, "R_s": -0.3},
        "dP", 0.8, 0.85,
        "a load riding high on a wide belt (P_max 1 m) passes over the flexible fence "
        "as it tops its swing; the tip rises to the middle of the load's bottom edge "
        "and falls back (no corner near the fence: the tip alone)"),
    "corner_rail": (
        "rail",
        {"L": 0.4, "A": 0.4, "R_s": -0.1},
        "dP", 0.0005, 0.002,
        "the flexible fence hits a square load near the rail and turns it; its "
        "rear-bottom corner dips to the rail and rises again while it is still "
        "upstream of the pivot (x < 0: at R_s = 0 it would still be going down when "
        "it passes x = 0, a hand-over to the fence rather than a graze)"),
    "tip_clip": (
        "tip",
        {"case": "small_far"},
        "v", 2.8, 3.0,
        "small_far on a fast belt escapes past the flexible fence and the rising tip "
        "clips the load's rear-bottom corner: tip and corner both touch (a corner "
        "passing the tip crosses the fence line just inside it), for ~1e-5 s at ~3 m/s, "
        "so the damping term of the law gives kN for a 2e-5 m penetration"),
}
PEAK_CHECK = 1e-6       # peak_force at RTOL and RTOL_CHECK must agree to this (relative)


def clearance(scene, kind, rtol=RTOL):
    """(signed clearance c [m], touched, result) of one reference run."""
    r = model.simulate_reference(scene, rtol=rtol)
    if r["status"] != "ok":
        raise RuntimeError(f"reference failed for {scene}: {r['status']}")
    # one of the two is 0; the geometric clearance can dip below 0 by less than the
    # reference's event resolution without a contact being registered (touched False)
    c = r["min_gap_" + kind] - r["max_pen_" + kind]
    return c, bool(r["touch_" + kind]), r


def describe(r):
    return (f"outcome {r['outcome']}, touches fence/tip/rail "
            f"{int(r['touch_fence'])}{int(r['touch_tip'])}{int(r['touch_rail'])}, "
            f"max_pen {r['max_pen_fence']:.3e}/{r['max_pen_tip']:.3e}/{r['max_pen_rail']:.3e} m, "
            f"min_gap {r['min_gap_fence']:.3e}/{r['min_gap_tip']:.3e}/{r['min_gap_rail']:.3e} m, "
            f"t_first_contact {r['t_first_contact']:.6f} s")


def nice(value, slope):
    """value rounded to the fewest decimals that move c by less than TARGET / 20."""
    for k in range(1, 12):
        r = round(float(value), k)
        if abs(r - value) * abs(slope) < TARGET / 20:
            return r
    return float(value)


def find(stem):
    kind, base, name, p_touch, p_miss, why = GRAZES[stem]
    print(f"== graze_{stem} / miss_{stem} ({kind} contact): {why}\n"
          f"   scene {base}, parameter {name}", flush=True)
    c_t, hit, _ = clearance({**base, name: p_touch}, kind)
    c_m, hit_m, _ = clearance({**base, name: p_miss}, kind)
    if not hit or hit_m:
        raise RuntimeError(f"{kind}: {name} = {p_touch} must touch and {p_miss} must not "
                           f"(got {hit}, {hit_m})")
    lo, hi = (p_touch, c_t), (p_miss, c_m)      # (parameter, clearance): touching, missing
    n = 2
    seen = [lo, hi]
    while max(-lo[1], hi[1]) > BRACKET_C:
        mid = 0.5 * (lo[0] + hi[0])
        c, hit, _ = clearance({**base, name: mid}, kind)
        seen.append((mid, c))
        n += 1
        if hit:
            lo = (mid, c)
        else:
            hi = (mid, c)
        print(f"   [{n:2d}] {name} = {mid:.12g}: {'touch' if hit else 'miss '} "
              f"c = {c:+.3e} m", flush=True)
    print(f"   bracket: {name} in [{lo[0]:.12g} (touch, c = {lo[1]:+.2e} m), "
          f"{hi[0]:.12g} (miss, c = {hi[1]:+.2e} m)] after {n} reference runs", flush=True)
    # c is smooth but not linear across the transition (the contact's force pushes back
    # on the touching side), so each target is reached by secant steps on its own side,
    # started from the two runs of that side nearest to it
    out = {}
    for label, c_want in (("graze", -TARGET), ("near miss", TARGET)):
        side = sorted((pc for pc in seen if pc[1] * c_want > 0),
                      key=lambda pc: abs(math.log(abs(pc[1]) / TARGET)))[:2]
        (p0, c0), (p1, c1) = side
        for _ in range(MAX_SECANT):
            slope = (c1 - c0) / (p1 - p0)               # dc / dparameter [m per unit]
            p0, c0 = p1, c1
            p1 = nice(p1 + (c_want - c1) / slope, slope)
            c1, hit, r = clearance({**base, name: p1}, kind)
            n += 1
            if abs(c1 - c_want) < 0.2 * TARGET or p1 == p0:
                break
        c2, hit2, r2 = clearance({**base, name: p1}, kind, rtol=RTOL_CHECK)
        dF = abs(r2["peak_force"] - r["peak_force"]) / max(r["peak_force"], 1e-300)
        ok = (hit == (label == "graze") == hit2) and WINDOW[0] <= abs(c1) <= WINDOW[1] \
            and abs(c2 - c1) < 0.01 * abs(c1) and (r["peak_force"] == 0.0 or dF < PEAK_CHECK)
        print(f"   {label:9s}: {name} = {p1!r}: c = {c1:+.4e} m at rtol {RTOL:g}, "
              f"{c2:+.4e} m at rtol {RTOL_CHECK:g}, dc/d{name} = {slope:.4g} m per unit; "
              f"peak_force {r['peak_force']:.6g} N ({dF:.1e} apart) "
              f"-> {'OK' if ok else 'NOT OK'}\n"
              f"              {describe(r)}", flush=True)
        out[label] = (p1, c1, ok)
    print(f"   {n} reference runs in all\n", flush=True)
    return out


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--only", choices=list(GRAZES), action="append",
                    help="graze(s) to look for (default: all)")
    args = ap.parse_args(argv)
    bad = []
    for stem in args.only or list(GRAZES):
        res = find(stem)
        bad += [f"{stem} {label}" for label, (_, _, ok) in res.items() if not ok]
    if bad:
        print("NOT within the window or not unambiguous: " + ", ".join(bad))
        sys.exit(1)


if __name__ == "__main__":
    main()
