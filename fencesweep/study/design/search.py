"""`fencesweep design SPEC.yaml`: the element that keeps every constraint for every load of an
envelope. Orchestration only: the engine is api.simulate_resolved.

The spec's `design:` section (checked by spec/design.py) names the design variables (B2,
K2, optionally any numeric §12 parameter such as m2, t_c, v) with their bounds, the constraints
(every load scraped, worst overload <= 1, worst deflection_max <= dalpha_perm, worst
residual_amplitude <= a threshold), the objective and the optimiser's settings. A design point
is judged over the spec's envelope of loads by envelope.summarize (the same judge as
`fencesweep grid`), and scipy.optimize.differential_evolution (seeded) searches the bounds. The
optimum, rounded to `digits` significant digits, is then checked on a fresh, denser sample of
the same envelope (another seed, `verify` points) and refined there by a bounded Nelder-Mead;
how far it moved is reported. The comparison designs (the paper's 72/570, the two-case
recommendation 15/2075, the rigid fence, ...) are judged on the same dense sample.

Objectives: `max_min_margin` (default) maximises the smallest margin, 1 - worst / limit over the
constraints (share_scraped - 1 for the scraped one): an infeasible point has a negative margin,
so the search also finds the best infeasible point of an empty region; `min_worst_overload`
minimises the worst overload among feasible points (infeasible ones score 10 - min_margin).
"""
from __future__ import annotations

import contextlib
import json
import math
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

import numpy as np

from fencesweep.model import params as P
from fencesweep.study.design import judge as J
from fencesweep.study.spec import design as DS
from fencesweep.study.spec import envelope as E
from fencesweep.study.spec import spec as S
from fencesweep.study.spec.design import DesignConfig
from fencesweep.study.sweep.progress import bar as progress_bar

INFEASIBLE_SCORE = 10.0


# ------------------------------------------------------------------------------ judging
RESULT_COLUMNS = ("outcome", "overload", "deflection_max", "residual_amplitude", "peak_force", "t_exit", "status")


def evaluate(spec, point: dict, loads: list, simulate: Callable | None = None):
    """Per-load table of one design point (design variables or any §12 overrides) over `loads`
    (tuples in the order of spec.envelope.names): load, the load's parameters, dalpha_perm and
    RESULT_COLUMNS."""
    import pandas as pd

    if simulate is None:
        from fencesweep.model.simulate import simulate_resolved as simulate
    names = spec.envelope.names
    entry = spec.cases[0]
    rows = []
    for k, load in enumerate(loads):
        over = {**spec.params, **entry["params"], **point, **dict(zip(names, load))}
        vals = S.resolve_inputs(spec.scene, entry["case"] or spec.case, over)
        res, _ = simulate(vals, trajectory=False)
        row = {"load": k, **dict(zip(names, load)), "dalpha_perm": vals["dalpha_perm"]}
        row.update({c: res[c] for c in RESULT_COLUMNS})
        rows.append(row)
    return pd.DataFrame(rows)


def stream_check(spec, point: dict, loads: list, limits: DS.Limits) -> dict | None:
    """The loads back to back (scene stream, docs/model.md §14) at period t_c, in the order given:
    what one cycle leaves in the element is what the next starts from. `safe`: every cycle
    scraped, worst overload and deflection within the limits. None when the envelope
    varies more than the load's parameters, or the element cannot run a stream (drive free)."""
    import pandas as pd

    from fencesweep.model import simulate as api
    names = spec.envelope.names
    if any(n not in P.LOAD_NAMES for n in names):
        return None
    entry = spec.cases[0]
    over = {**spec.params, **entry["params"], **point}
    table = pd.DataFrame([list(x) for x in loads], columns=list(names))
    try:
        vals = S.resolve_inputs("stream", entry["case"] or spec.case, over, table)
    except P.ParameterError:
        return None
    res, _ = api.simulate_resolved(vals)
    cyc = res["cycles"]
    dlim = vals["dalpha_perm"] if limits.deflection_max is None else limits.deflection_max
    # safe as in REPORT.md §6 (report.stream_safety): every cycle scraped within the overload and
    # deflection limits; the start amplitude, the stream's answer to the residual criterion, is reported
    safe = (res["n_scraped"] == res["n_cycles"] and res["worst_overload"] <= limits.overload
            and res["worst_deflection"] <= dlim)
    return {"n_cycles": int(res["n_cycles"]), "n_scraped": int(res["n_scraped"]),
            "first_failure": int(res["first_failure"]), "worst_overload": float(res["worst_overload"]),
            "worst_deflection": float(res["worst_deflection"]),
            "worst_start_amplitude": float(res["worst_start_amplitude"]), "period": float(vals["period"]),
            "worst_overload_cycle": int(cyc["overload"].to_numpy().argmax()), "safe": bool(safe)}


def judge(per_load, limits: DS.Limits) -> dict:
    """One design point's summary (envelope.summarize over all its loads) as a dict."""
    return J.summarize(per_load, [], limits).iloc[0].to_dict()


def score(summary: dict, objective: str) -> float:
    """The value the optimiser minimises (module docstring)."""
    if objective == "max_min_margin":
        return -float(summary["min_margin"])
    if summary["feasible"]:
        return float(summary["worst_overload"])
    return INFEASIBLE_SCORE - float(summary["min_margin"])


# the optimiser's context, set in this process before the worker processes fork
_CTX: dict = {}


def _objective(x: np.ndarray) -> float:
    return _score(x, _CTX)


def _score(x: np.ndarray, shared: dict) -> float:
    """The optimiser's objective at `x` in the context `shared` (spec, cfg, loads, simulate,
    floor): _CTX in this process and its forked workers, an argument on a Dask worker."""
    spec, cfg, loads = shared["spec"], shared["cfg"], shared["loads"]
    point = dict(zip(cfg.variables, (float(v) for v in x)))
    summary = judge(evaluate(spec, point, loads, shared.get("simulate")), cfg.limits)
    floor = shared.get("floor")
    if floor is None:
        return score(summary, cfg.objective)
    return prefer_score(point, summary, cfg, floor)


def prefer_score(point: dict, summary: dict, cfg: DesignConfig, floor: float) -> float:
    """The second stage of max_min_margin with `prefer`: among points whose smallest margin is at
    least `floor`, the smallest (or largest) preferred variable, as a fraction of its range in
    [0, 1]; a point below the floor scores 1 + 10 x its shortfall."""
    if summary["min_margin"] < floor:
        return 1.0 + 10.0 * (floor - float(summary["min_margin"]))
    name, way = cfg.prefer
    lo, hi = cfg.variables[name]
    frac = (point[name] - lo) / (hi - lo)
    return frac if way == "min" else 1.0 - frac


def round_sig(x: float, digits: int) -> float:
    if x == 0 or not math.isfinite(x):
        return float(x)
    return float(f"{x:.{digits}g}")


@dataclass
class Found:
    """What the search found: the optimum, how the optimiser ended, and its cost."""

    point: dict
    raw: dict
    score: float
    converged: bool
    message: str
    nit: int
    nfev: int
    seconds: float


def search(spec, cfg: DesignConfig, jobs: int = 1, progress: bool = False, simulate: Callable | None = None,
           log: Callable[[str], None] = lambda m: None, floor: float | None = None,
           scheduler: str | None = None) -> Found:
    """differential_evolution over cfg.variables, each point judged over the spec's envelope; with
    `floor`, the second stage (prefer_score). The points of a generation are judged on `jobs`
    local processes or, given `scheduler`, on that Dask cluster's workers (_workers): the result
    is the same (updating="deferred")."""
    from scipy.optimize import differential_evolution

    _CTX.update(spec=spec, cfg=cfg, loads=spec.envelope.loads, simulate=simulate, floor=floor)
    bounds = list(cfg.variables.values())
    bar = _bar(cfg.maxiter, "design" if floor is None else f"prefer {cfg.prefer[1]} {cfg.prefer[0]}", progress)
    t0 = time.perf_counter()

    def callback(intermediate_result):
        bar.update(1)
        bar.set_postfix_str(f"best {intermediate_result.fun:.4f}")

    try:
        with _workers(jobs, scheduler) as workers:
            res = differential_evolution(_objective, bounds, seed=cfg.seed, maxiter=cfg.maxiter, popsize=cfg.popsize,
                                         tol=cfg.tol, polish=False, updating="deferred",  # the same for any jobs
                                         workers=workers, callback=callback, init="sobol")
    finally:
        bar.close()
    raw = dict(zip(cfg.variables, map(float, res.x)))
    point = {k: round_sig(v, cfg.digits) for k, v in raw.items()}
    point = {k: min(max(v, cfg.variables[k][0]), cfg.variables[k][1]) for k, v in point.items()}
    if not res.success:
        log(f"note: the optimiser did not converge ({res.message}); the best point found is used")
    return Found(point, raw, float(res.fun), bool(res.success), str(res.message), int(res.nit), int(res.nfev),
                 time.perf_counter() - t0)


@contextlib.contextmanager
def _workers(jobs: int, scheduler: str | None):
    """scipy's `workers` for the context in _CTX: 1 (this process), the map of `jobs` forked
    processes (which inherit _CTX), or, given `scheduler`, a map over the Dask cluster's workers
    (sweep/cluster.py mapper: _score with the context sent once; each worker warmed up first)."""
    if scheduler is not None:
        from fencesweep.study.sweep import cluster

        spec = _CTX["spec"]
        with cluster.mapper(scheduler, _score, dict(_CTX),
                            warm=(spec, cluster.first_rows(spec), _CTX.get("simulate"))) as workers:
            yield workers
    elif jobs > 1:
        import multiprocessing

        pool = multiprocessing.get_context("fork").Pool(jobs)
        try:
            yield pool.map
        finally:
            pool.terminate()
    else:
        yield 1


def _bar(total: int, desc: str, enabled: bool):
    return progress_bar(total, desc, enabled, unit="generation", leave=False)


def refine(spec, cfg: DesignConfig, start: dict, loads: list, simulate: Callable | None = None,
           floor: float | None = None) -> dict:
    """A bounded Nelder-Mead from `start` on the dense sample `loads`: where the optimum moves
    when judged on more loads. Returns the refined point (rounded) and its score."""
    from scipy.optimize import minimize

    _CTX.update(spec=spec, cfg=cfg, loads=loads, simulate=simulate, floor=floor)
    names = list(cfg.variables)
    x0 = np.array([start[n] for n in names])
    lo = np.array([cfg.variables[n][0] for n in names])
    hi = np.array([cfg.variables[n][1] for n in names])
    simplex = [x0]
    for i in range(len(names)):  # a step of 5 % of the bounds along each variable, inwards at a bound
        step = 0.05 * (hi[i] - lo[i])
        x = x0.copy()
        x[i] = x0[i] + step if x0[i] + step <= hi[i] else x0[i] - step
        simplex.append(x)
    simplex = np.vstack(simplex)
    res = minimize(_objective, x0, method="Nelder-Mead", bounds=list(zip(lo, hi)),
                   options={"maxfev": cfg.refine, "initial_simplex": simplex, "xatol": 1e-3, "fatol": 1e-4})
    point = {n: round_sig(float(v), cfg.digits) for n, v in zip(names, res.x)}
    margin = judge(evaluate(spec, point, loads, simulate), cfg.limits)["min_margin"]
    return {"point": point, "score": float(res.fun), "nfev": int(res.nfev), "min_margin": float(margin)}


# ------------------------------------------------------------------------------ the study
def dense_loads(spec, cfg: DesignConfig) -> tuple:
    """A fresh, denser sample of the spec's envelope (cfg.verify_*): (loads, skipped)."""
    env = spec.envelope
    probe = E.Envelope(dims=env.dims, corners=env.corners, method=cfg.verify_method, names=env.names)
    return E.valid_loads(probe, spec.load_base(), cfg.verify_n, cfg.verify_seed, env.corners)


def _row(label: str, point: dict, summary: dict, loads_of: Callable) -> dict:
    out = {"design": label, **{k: point.get(k) for k in ("drive", "B2", "K2")}, **point}
    out.update({k: summary[k] for k in ("n_loads", "share_scraped", "n_escaped", "worst_overload",
                                        "worst_deflection_max", "worst_residual_amplitude", *J.MARGINS,
                                        "min_margin", "binding", "feasible")})
    for col in ("overload", "deflection_max", "residual_amplitude"):
        out[f"worst_{col}_load"] = loads_of(int(summary[f"worst_{col}_load"]))
    return out


def run_design(spec, jobs: int = 1, progress: bool = False, out_dir: str | Path | None = None,
               simulate: Callable | None = None, log: Callable[[str], None] = lambda m: None,
               scheduler: str | None = None) -> dict:
    """The whole study: search (on `jobs` processes or, given `scheduler`, on that Dask cluster),
    verify on a dense sample, refine, compare (in this process); write OUT/recommended.json,
    OUT/comparison.parquet and OUT/verify_loads.parquet. Returns the recommendation (the JSON's
    content)."""
    import pandas as pd

    from fencesweep.study.store import table as store

    cfg = spec.design
    out = Path(out_dir or cfg.output)
    t0 = time.perf_counter()
    env = spec.envelope
    found = search(spec, cfg, jobs, progress, simulate, log, scheduler=scheduler)
    best = None
    if cfg.prefer is not None:  # among the points within `within` of the best smallest margin
        best = found
        found = search(spec, cfg, jobs, progress, simulate, log, floor=-best.score - cfg.within, scheduler=scheduler)
    on_sample = judge(evaluate(spec, found.point, env.loads, simulate), cfg.limits)
    loads, skipped = dense_loads(spec, cfg)
    if skipped:
        log(f"verification sample: {len(skipped)} loads cannot start on the belt and are left out")
    names = env.names
    dense_of = lambda k: dict(zip(names, loads[k]))  # noqa: E731
    per_load, rows = [], []
    designs = {"envelope recommendation": found.point, **cfg.compare}
    for label, point in designs.items():
        pl = evaluate(spec, point, loads, simulate).assign(design=label)
        per_load.append(pl)
        rows.append(_row(label, point, judge(pl, cfg.limits), dense_of))
        st = stream_check(spec, point, loads, cfg.limits)
        rows[-1].update({f"stream_{k}": v for k, v in (st or {}).items()})
    verified = rows[0]
    floor = None
    if best is not None:  # the same second stage on the fresh loads: the floor from their best margin
        floor = judge(evaluate(spec, best.point, loads, simulate), cfg.limits)["min_margin"] - cfg.within
    moved = refine(spec, cfg, found.point, loads, simulate, floor) if cfg.refine else None
    table = pd.DataFrame(rows)
    store.write_table_atomic(_arrow(table), out / "comparison.parquet")
    store.write_table_atomic(_arrow(pd.concat(per_load, ignore_index=True)), out / "verify_loads.parquet")
    rec = _recommendation(spec, cfg, found, on_sample, verified, moved, loads, skipped, time.perf_counter() - t0)
    if best is not None:
        rec["largest_margin"] = {"design_variables": best.point, "min_margin": -best.score,
                                 "generations": best.nit, "evaluations": best.nfev, "converged": best.converged,
                                 "cycles": best.nfev * len(env.loads)}
    rec["comparison"] = [{k: _plain(v) for k, v in r.items()} for r in rows]
    out.mkdir(parents=True, exist_ok=True)
    with store.atomic_path(out / "recommended.json") as tmp:
        tmp.write_text(json.dumps(rec, indent=1, allow_nan=False) + "\n")
    return rec


def _arrow(df):
    import pyarrow as pa

    return pa.Table.from_pandas(df.map(lambda v: json.dumps(v) if isinstance(v, dict) else v), preserve_index=False)


def _plain(v):
    if hasattr(v, "item"):
        v = v.item()
    if isinstance(v, float) and not math.isfinite(v):
        return None
    return v


def at_bounds(point: dict, cfg: DesignConfig) -> dict:
    """The design variables within 1 % of their range from a bound: name -> 'lower' / 'upper'."""
    out = {}
    for k, (lo, hi) in cfg.variables.items():
        tol = 0.01 * (hi - lo)
        if point[k] <= lo + tol:
            out[k] = "lower"
        elif point[k] >= hi - tol:
            out[k] = "upper"
    return out


def _status(verified: dict, found: Found) -> str:
    if not verified["feasible"]:
        return (f"infeasible: no element in the bounds keeps every constraint for every load; the best point "
                f"found breaks {verified['binding']} (margin {verified['min_margin']:.3f})")
    return "feasible" + ("" if found.converged else " (the optimiser did not converge: best point found)")


def _recommendation(spec, cfg, found, on_sample, verified, moved, loads, skipped, seconds) -> dict:
    from fencesweep.study.store import table as store

    fixed = dict(spec.params, **spec.cases[0]["params"])
    margins = {k.removeprefix("margin_"): _plain(verified[k]) for k in J.MARGINS}
    rec = {
        "status": _status(verified, found),
        "design_variables": found.point,
        "fixed": {k: _plain(v) for k, v in fixed.items()},
        "case": spec.cases[0]["case"] or spec.case,
        "objective": cfg.objective,
        "constraints": cfg.limits.as_dict(),
        "units": {n: P.BY_NAME[n].unit for n in list(found.point) + ["dalpha_perm"]} | {
            "deflection_max": "rad", "residual_amplitude": "rad", "overload": "-"},
        "at_bounds": at_bounds(found.point, cfg),
        "margins": margins,
        "worst": {k: _plain(verified[k]) for k in ("worst_overload", "worst_deflection_max",
                                                     "worst_residual_amplitude", "share_scraped", "binding")},
        "worst_loads": {k: verified[f"worst_{k}_load"] for k in ("overload", "deflection_max", "residual_amplitude")},
        "optimisation_sample": {"n_loads": len(spec.envelope.loads),
                                "min_margin": _plain(on_sample["min_margin"]),
                                "margins": {k.removeprefix("margin_"): _plain(on_sample[k]) for k in J.MARGINS}},
        "verification": {"n_loads": len(loads), "n_skipped": len(skipped), "method": cfg.verify_method,
                         "seed": cfg.verify_seed, "min_margin": _plain(verified["min_margin"]),
                         "min_margin_change": _plain(verified["min_margin"] - on_sample["min_margin"])},
        "optimizer": {"converged": found.converged, "message": found.message, "generations": found.nit,
                      "evaluations": found.nfev, "cycles": found.nfev * len(spec.envelope.loads),
                      "seconds": round(found.seconds, 1), "raw_optimum": found.raw, "score": found.score},
        "envelope": {**spec.envelope.definition(), "names": list(spec.envelope.names),
                     "loads": [list(x) for x in spec.envelope.loads]},
        "design": cfg.as_dict(),
        "spec_hash": spec.hash, "spec_path": spec.path, "versions": store.versions(),
        "seconds": round(seconds, 1),
    }
    if moved is not None:
        rec["refined_on_verification_sample"] = {
            **moved, "moved": {k: moved["point"][k] - found.point[k] for k in found.point},
            "moved_relative_to_bounds": {k: (moved["point"][k] - found.point[k]) / (hi - lo)
                                         for k, (lo, hi) in cfg.variables.items()}}
    return rec


# ------------------------------------------------------------------------------ terminal
def _fmt_load(load: dict) -> str:
    return ", ".join(f"{k} = {v:g}" for k, v in load.items() if not isinstance(v, str))


def summary_lines(rec: dict) -> list:
    """What `fencesweep design` prints: the status, the element, its margins and worst loads,
    the verification, the optimiser's ending and the comparison table."""
    dv = ", ".join(f"{k} = {v:g}" for k, v in rec["design_variables"].items())
    ver, opt = rec["verification"], rec["optimizer"]
    lines = [f"status: {rec['status']}", f"recommended: {dv}",
             "margins (1 - worst / limit, over {} loads of the verification sample): ".format(ver["n_loads"])
             + ", ".join(f"{k} {v:.3f}" for k, v in rec["margins"].items() if v is not None)]
    for k, side in rec.get("at_bounds", {}).items():
        lo, hi = rec["design"]["variables"][k]["min"], rec["design"]["variables"][k]["max"]
        lines.append(f"note: {k} = {rec['design_variables'][k]:g} is at the {side} bound of its range [{lo:g}, {hi:g}]: "
                     f"the best element may lie beyond it")
    for k, load in rec["worst_loads"].items():
        lines.append(f"  worst load for {k}: {_fmt_load(load)}")
    lines.append(f"optimiser: {'converged' if opt['converged'] else 'NOT converged'} ({opt['message']}) after "
                 f"{opt['generations']} generations, {opt['evaluations']} design points, {opt['cycles']} cycles, "
                 f"{opt['seconds']} s")
    lines.append(f"smallest margin: {rec['optimisation_sample']['min_margin']:.3f} on the {rec['optimisation_sample']['n_loads']} "
                 f"loads searched, {ver['min_margin']:.3f} on {ver['n_loads']} fresh loads "
                 f"({ver['min_margin_change']:+.3f})")
    ref = rec.get("refined_on_verification_sample")
    if ref:
        lines.append("refined on the fresh loads: " + ", ".join(f"{k} = {v:g}" for k, v in ref["point"].items())
                     + " (moved " + ", ".join(f"{k} {v:+g}" for k, v in ref["moved"].items())
                     + f"; smallest margin {ref['min_margin']:.3f})")
    big = rec.get("largest_margin")
    if big:
        pv = next(iter(rec["design"]["prefer"].items()))
        lines.append(f"largest smallest margin: {big['min_margin']:.3f} at "
                     + ", ".join(f"{k} = {v:g}" for k, v in big["design_variables"].items())
                     + f"; recommended: the {'least' if pv[1] == 'min' else 'largest'} {pv[0]} within "
                     f"{rec['design']['within']:g} of it")
    lines.append("")
    lines += comparison_lines(rec["comparison"])
    return lines


def comparison_lines(rows: list) -> list:
    """The comparison as a Markdown table (angles in degrees)."""
    out = ["| design | scraped | worst overload | worst deflection_max [deg] | worst residual_amplitude [deg] | "
           "smallest margin | binding | feasible |", "|---|---|---|---|---|---|---|---|"]
    for r in rows:
        out.append(f"| {r['design']} | {r['share_scraped'] * 100:.0f} % | {r['worst_overload']:.3f} | "
                   f"{math.degrees(r['worst_deflection_max']):.2f} | {math.degrees(r['worst_residual_amplitude']):.2f} | "
                   f"{r['min_margin']:.3f} | {r['binding']} | {'yes' if r['feasible'] else 'no'} |")
    return out
