"""Adaptive maps against the full grid, side by side in one run.

    python benchmarks/adaptive.py [--jobs 2] [--only NAME ...]   -> prints, writes results/adaptive.md
                                                                   and results/figures/adaptive_*.png

For each study, on this machine, one after the other: the full grid (`fencesweep.grid(spec)`)
and the adaptive map (`fencesweep.grid(spec, adaptive=True)`), both with `verify=False` (the
verification's cost is the same share of either), into a temporary folder. Reported: cycles run
(the coarse pass included), wall time of the whole call, design points whose verdict differs from
the full grid's (the full grid's table judged per design point: adaptive_points.full_points), and
among the feasible points those whose binding constraint differs.

Studies: sweeps/envelope.yaml (81 x 81 x 64 loads), two variants in benchmarks/specs/ (another
working point and load box with 32 loads on 65 x 65; a tighter deflection limit where three
constraints bind, 24 loads), and sweeps/b2k2.yaml (a grid with two cases: verdict ok = scraped,
overload <= 1, deflection within dalpha_perm).

python-adaptive against the own refinement: on each envelope study's full-grid map (min_margin
clipped to [-1, 1], looked up at the nearest grid point: no engine runs), adaptive.Learner2D with
its default loss and with a level-set loss (a triangle's size counts only where its corners'
signs differ) asks batches of 16 points; the design points it needs before its interpolation
classifies the grid within 0.5 %, against the design points the own refinement simulated.
"""
from __future__ import annotations

import argparse
import contextlib
import json
import math
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
# this script is named adaptive.py: its folder must not hide the package `adaptive` (python-adaptive)
sys.path[:] = [p for p in sys.path if Path(p or ".").resolve() != Path(__file__).resolve().parent]
STUDIES = {
    "envelope": "sweeps/envelope.yaml",
    "working_point": "benchmarks/specs/adaptive_working_point.yaml",
    "three_bind": "benchmarks/specs/adaptive_three_bind.yaml",
    "b2k2_cases": "sweeps/b2k2.yaml",
}
#: what an adaptive map must do to replace the full grid: run at most this share of its cycles,
#: and classify at most this share of the design points differently
BAR_SHARE, BAR_WRONG = 0.10, 0.005
# Learner2D keeps refining around the boundary between grid points (its points are continuous):
# past this many points (minutes of its own bookkeeping) it stops short of the budget
MAX_LEARNER_POINTS = 2500


def run_study(name: str, path: str, jobs: int, tmp: Path) -> dict:
    import fencesweep
    from fencesweep.study.adaptive import maps as AM
    from fencesweep.study.adaptive import points as APT
    from fencesweep.study.api import load_spec

    spec = load_spec(ROOT / path)
    lay = AM.layout(spec)
    full_out, timing = tmp / f"{name}_full.parquet", tmp / f"{name}_full.json"
    kept = timing.exists() and full_out.exists()
    if kept:  # --keep: the full grid of an earlier run, and its time
        from fencesweep.study.store import table as store

        full, t_full = store.read_table(full_out), json.loads(timing.read_text())["seconds"]
        print(f"{name}: the full grid and its time from {full_out} (--keep)", flush=True)
    else:
        t = time.perf_counter()
        full = fencesweep.grid(spec, out=full_out, jobs=jobs, verify=False, overwrite=True, resume=False)
        t_full = time.perf_counter() - t
        timing.write_text(json.dumps({"seconds": t_full}))
    t = time.perf_counter()
    ad = fencesweep.grid(spec, out=tmp / f"{name}_adaptive.parquet", jobs=jobs, verify=False, overwrite=True,
                         adaptive=True, resume=False)
    t_ad = time.perf_counter() - t
    v = APT.verdict_name(lay)
    ref = APT.full_points(lay, full)
    pts = fencesweep.points(ad)
    rec = ad.attrs["run"]["adaptive"]
    wrong = pts[v].to_numpy() != ref[v].to_numpy()
    both = pts[v].to_numpy() & ref[v].to_numpy()
    bind = both & (pts["binding"].to_numpy() != ref["binding"].to_numpy())
    # the rows of T are the full grid's rows of the same scenes (same engine, same parameters)
    same_rows = _rows_agree(full, ad)
    return {"name": name, "spec": path, "shape": lay.grid.shape, "maps": lay.grid.n_maps, "loads": lay.n_loads,
            "full_cycles": len(full), "cycles": len(ad), "t_full": t_full, "t_adaptive": t_ad,
            "points": len(pts), "wrong": int(wrong.sum()), "wrong_sampled": int((wrong & pts["sampled"].to_numpy()).sum()),
            "binding_differs": int(bind.sum()), "feasible_full": int(ref[v].sum()), "sampled": int(pts["sampled"].sum()),
            "rows_agree": same_rows, "kept": kept, "record": rec, "verdict": v, "lay": lay, "ref": ref, "pts": pts, "wrong_mask": wrong}


def _rows_agree(full, ad) -> bool:
    """T's rows equal the full grid's rows of the same scenes (the numeric columns, NaN = NaN)."""
    import pandas as pd

    key = [c for c in ("B2", "K2", "case", "L", "A", "m1", "dP") if c in ad.columns]
    cols = [c for c in ("peak_force", "overload", "deflection_max", "residual_amplitude", "t_exit") if c in ad.columns]
    m = ad[key + cols].merge(full[key + cols], on=key, how="left", suffixes=("", "_full"))
    return bool(len(m) == len(ad) and all(
        np.array_equal(m[c].to_numpy(float), m[c + "_full"].to_numpy(float), equal_nan=True) for c in cols)
        and pd.notna(m[cols[0] + "_full"]).sum() >= pd.notna(m[cols[0]]).sum())


# ---- python-adaptive on the full grid's map ---------------------------------------------------
def level_set_loss(ip):
    """Learner2D loss: a triangle's area where its corners' signs differ (the boundary), else a
    thousandth of it (so the map is still filled in slowly)."""
    from adaptive.learner.learner2D import areas

    vals = ip.values.ravel()[ip.tri.simplices]
    crosses = (vals.min(axis=1) < 0) & (vals.max(axis=1) >= 0)
    return np.sqrt(areas(ip)) * np.where(crosses, 1.0, 1e-3)


def learner_needs(margin: np.ndarray, feasible: np.ndarray, budget: int, loss=None, batch: int = 16) -> dict:
    """Learner2D on one map (margin, feasible: [nx, ny]) until it has evaluated `budget` distinct
    grid points: the points it had when its interpolation first classified the grid within
    BAR_WRONG (an oracle stop: a real run does not know the answer), and its share classified
    differently at `budget` points."""
    import adaptive

    nx, ny = margin.shape
    seen: set = set()

    def f(xy):
        i, j = int(round(xy[0])), int(round(xy[1]))
        seen.add((i, j))
        return float(np.clip(margin[i, j], -1.0, 1.0))

    kw = {"loss_per_triangle": loss} if loss is not None else {}
    learner = adaptive.Learner2D(f, bounds=[(0, nx - 1), (0, ny - 1)], **kw)
    gx, gy = np.meshgrid(np.arange(nx), np.arange(ny), indexing="ij")
    grid = np.stack([gx.ravel(), gy.ravel()], axis=1)
    first, wrong = None, 1.0
    while len(seen) < min(budget, nx * ny) and learner.npoints < MAX_LEARNER_POINTS:
        xs, _ = learner.ask(batch)
        learner.tell_many(xs, [f(x) for x in xs])
        if learner.npoints >= 3 + batch:
            pred = learner.interpolator(scaled=False)(grid).ravel() >= 0.0
            wrong = float(np.mean(pred != feasible.ravel()))
            if first is None and wrong <= BAR_WRONG:
                first = len(seen)
    return {"points": first, "wrong_at_budget": wrong, "budget": len(seen), "learner_points": learner.npoints}


def compare_learner(r: dict) -> dict:
    """Learner2D (default and level-set loss) on the first map of study r, against the own refinement."""
    lay, ref, pts = r["lay"], r["ref"], r["pts"]
    shape = lay.grid.shape
    if len(shape) != 2:
        return {}
    size = int(np.prod(shape))
    margin = ref["min_margin"].to_numpy()[:size].reshape(shape)
    feas = ref[r["verdict"]].to_numpy()[:size].reshape(shape)
    own = int(pts["sampled"].to_numpy()[:size].sum())
    own_wrong = float(r["wrong_mask"][:size].mean())
    return {"own": own, "own_wrong": own_wrong, "default": learner_needs(margin, feas, own),
            "level_set": learner_needs(margin, feas, own, level_set_loss)}


# ---- the figure ---------------------------------------------------------------------------------
def figure(r: dict, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.colors import ListedColormap

    lay, ref, pts = r["lay"], r["ref"], r["pts"]
    shape, maps = lay.grid.shape, lay.grid.n_maps
    size = int(np.prod(shape))
    names = [lay.spec.axes[p].names[0] for p in lay.refined]
    axes_vals = [np.array([v[0] for v in lay.spec.axes[p].values], dtype=float) for p in lay.refined]
    fig, axs = plt.subplots(1, maps, figsize=(6.2 * maps, 5.4), squeeze=False)
    for k in range(maps):
        ax = axs[0, k]
        sl = slice(k * size, (k + 1) * size)
        feas = ref[r["verdict"]].to_numpy()[sl].reshape(shape)
        x, y = axes_vals
        ax.pcolormesh(x, y, feas.T.astype(float), cmap=ListedColormap(["#f4c7c3", "#cfe8cf"]), vmin=0, vmax=1,
                      shading="nearest")
        codes = {b: i for i, b in enumerate(sorted(set(ref["binding"])))}
        bind = np.array([codes[b] for b in ref["binding"].to_numpy()[sl]], dtype=float).reshape(shape)
        if len(codes) > 1:
            ax.contour(x, y, bind.T, levels=np.arange(len(codes) - 1) + 0.5, colors="0.35", linewidths=0.7,
                       linestyles="dashed")
        gx, gy = np.meshgrid(x, y, indexing="ij")
        s = pts["sampled"].to_numpy()[sl].reshape(shape)
        ax.scatter(gx[s], gy[s], s=2.5, c="k", lw=0, label=f"simulated ({int(s.sum())} of {size})")
        w = r["wrong_mask"][sl].reshape(shape)
        if w.any():
            ax.scatter(gx[w], gy[w], s=30, facecolors="none", edgecolors="#1f4fd1", lw=1.2,
                       label=f"verdict differs from the full grid ({int(w.sum())})")
        ax.set_xlabel(names[0])
        ax.set_ylabel(names[1])
        title = r["name"] + (f": {pts['case'].iloc[k * size]}" if "case" in pts.columns else "")
        ax.set_title(f"{title}\ngreen: {r['verdict']} (full grid), red: not; dashed: the binding constraint "
                     f"changes", fontsize=9)
        ax.legend(loc="upper right", fontsize=8, framealpha=0.9)
    fig.suptitle(f"{r['name']}: {r['cycles']} of {r['full_cycles']} cycles "
                 f"({r['cycles'] / r['full_cycles']:.1%}), {r['wrong']} of {r['points']} design points differ",
                 fontsize=11)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


# ---- the report -------------------------------------------------------------------------------
def report(results: list, learners: dict, jobs: int) -> str:
    lines = ["# Adaptive maps against the full grid", "",
             f"`python benchmarks/adaptive.py --jobs {jobs}`: each study's full grid and adaptive map, one after "
             "the other in one run on this machine (2 cores), both without the verification. `cycles`: every "
             "cycle run, the coarse pass included. `differ`: design points whose verdict differs from the full "
             "grid's (the bars: <= 0.5 % from <= 1/10 of the cycles). `binding differs`: feasible points "
             "whose binding constraint differs. `T = full rows`: the adaptive table's rows equal the full grid's "
             "rows of the same scenes.", "",
             "| study | grid x loads | full cycles | adaptive cycles | share | full s | adaptive s | speed-up | "
             "simulated points | differ | binding differs | T = full rows | bars |",
             "|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---|---|"]
    for r in results:
        share = r["cycles"] / r["full_cycles"]
        wrong = r["wrong"] / r["points"]
        ok = "met" if share <= BAR_SHARE and wrong <= BAR_WRONG else "**not met**"
        grid = " x ".join(map(str, r["shape"])) + (f" x {r['maps']} maps" if r["maps"] > 1 else "")
        lines.append(f"| {r['name']} | {grid} x {r['loads']} | {r['full_cycles']} | {r['cycles']} | {share:.1%} | "
                     f"{r['t_full']:.1f}{'*' if r['kept'] else ''} | {r['t_adaptive']:.1f} | {r['t_full'] / r['t_adaptive']:.1f}x | "
                     f"{r['sampled']} of {r['points']} | {r['wrong']} ({wrong:.2%}) | {r['binding_differs']} | "
                     f"{'yes' if r['rows_agree'] else 'NO'} | {ok} |")
    if any(r["kept"] for r in results):
        lines += ["", "\\* the full grid's table and wall time from an earlier invocation of this script on the same "
                      "machine (`--keep DIR`), minutes before the adaptive run."]
    lines += ["", "Per study, what the refinement did (the table's metadata `fencesweep.adaptive`):", ""]
    for r in results:
        rec = r["record"]
        lv = ", ".join(f"step {x['step']}: {x['simulated']} simulated, {x['inferred_on_faces']} inferred"
                       for x in rec["levels"])
        lines.append(f"* **{r['name']}** ({r['spec']}): {rec['simulated']} design points simulated, "
                     f"{rec['inferred']} inferred; {rec['stopped_at_a_broken_constraint']} stopped at the first "
                     f"load that broke a constraint, {rec['feasible_with_predicted_loads']} feasible with "
                     f"{rec['loads_predicted']} loads predicted safe; differing verdicts on simulated points: "
                     f"{r['wrong_sampled']}. Levels: {lv}. Figure: results/figures/adaptive_{r['name']}.png")
    if learners:
        lines += ["", "## python-adaptive against the own refinement", "",
                  "Learner2D (python-adaptive) on each envelope study's full-grid map (its first map; min_margin "
                  "over every load, clipped to [-1, 1], at the nearest grid point; batches of 16): the distinct design "
                  "points it had evaluated when its linear interpolation first classified the grid within 0.5 % "
                  "(an *oracle stop*: it needs the full grid's answer, which a real run does not have), and its "
                  "share classified differently once it had as many points as the own refinement simulated. The own "
                  "refinement stops by its own rule (every cell settled) and its margins are those of the loads it "
                  "ran.", "",
                  "| study | own: points simulated | own: differ | Learner2D default loss: points at 0.5 % (oracle) "
                  "| differ at the own count | Learner2D level-set loss: points at 0.5 % (oracle) | differ at the own "
                  "count |", "|---|---:|---:|---:|---:|---:|---:|"]
        for name, c in learners.items():
            if c:
                d, ls = c["default"], c["level_set"]
                lines.append(f"| {name} | {c['own']} | {c['own_wrong']:.2%} | {d['points']} | "
                             f"{d['wrong_at_budget']:.2%} ({d['budget']}) | {ls['points']} | "
                             f"{ls['wrong_at_budget']:.2%} ({ls['budget']}) |")
        lines += ["", f"In brackets: the distinct design points Learner2D had reached when compared (it stops at "
                      f"{MAX_LEARNER_POINTS} of its own points: near the boundary it keeps asking points between "
                      f"grid points that round to ones it has)."]
    return "\n".join(lines) + "\n"


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--only", nargs="*", choices=list(STUDIES), default=None)
    ap.add_argument("--out", default=str(ROOT / "results" / "adaptive.md"))
    ap.add_argument("--keep", metavar="DIR", help="keep the tables in DIR; a full grid found there (with its time) "
                                                   "is not run again")
    args = ap.parse_args()
    results, learners = [], {}
    with (contextlib.nullcontext(args.keep) if args.keep else
          tempfile.TemporaryDirectory(prefix="fencesweep-adaptive-")) as tmp:
        Path(tmp).mkdir(parents=True, exist_ok=True)
        for name in args.only or STUDIES:
            r = run_study(name, STUDIES[name], args.jobs, Path(tmp))
            print(f"{name}: {r['cycles']} of {r['full_cycles']} cycles ({r['cycles'] / r['full_cycles']:.1%}), "
                  f"{r['t_adaptive']:.1f} s against {r['t_full']:.1f} s; {r['wrong']} of {r['points']} differ, "
                  f"binding {r['binding_differs']}, rows agree {r['rows_agree']}", flush=True)
            figure(r, ROOT / "results" / "figures" / f"adaptive_{name}.png")
            if r["lay"].mode == "envelope":
                learners[name] = compare_learner(r)
                print(f"  Learner2D: {learners[name]}", flush=True)
            results.append(r)
    text = report(results, learners, args.jobs)
    Path(args.out).write_text(text)
    print(text)
    return 0 if all(math.isfinite(r["t_full"]) for r in results) else 1


if __name__ == "__main__":
    sys.exit(main())
