"""Every sweep checks itself (sweeps/README.md, Verification): a sample of its model runs is run
again at a 10x tighter tolerance and the table's results are compared with the re-run's; the
record goes into the table's schema metadata (`fencesweep.verify`), the summary on stderr.

* The sample (sweep/sample.py): at least 16 runs or 1 %, the extremes first (highest
  peak_force and overload, largest deflection, smallest margins, most steps, grazes), then
  random, seeded; the re-runs cost at most ~5 % of the table's integrator steps.
* A tighter tolerance: the engine's tolerance is TOL x step_factor^5 (kernel/numerics.py), so
  the re-run is the same scene, its other parameters unchanged, with step_factor x
  STEP_FACTOR_SCALE = 10^(-1/5): tol / 10 (for integrator rk4, whose dt scales with
  step_factor too, dt x 0.63). A stream is re-run whole.
* The comparison (sweep/accuracy.py): per result, the largest relative difference
  |rerun - table| / max(|table|, floor) over the sample (over the runs, or cycles, whose
  outcomes agree), with the floors the validation uses; outcomes that differ are counted; a
  result defined in one and undefined (NaN) in the other counts as `undefined`.
* The verdict: `ok` false when a difference exceeds THRESHOLD (accuracy.AGREEMENT, 1e-3: the
  bound of docs/model.md (15.15) for two implementations of the model), an outcome differs or a result
  is undefined in only one of the two.
* What it did not see: of the n rows drawn uniformly at random (sweep/sample.py), k are over
  (a difference above THRESHOLD, an outcome that differs or a result defined in one only);
  `random.share_over_bound` is the one-sided CONFIDENCE upper bound on the share of the
  table's rows that are over, Clopper-Pearson's (exact for a binomial draw; 0 of n gives
  1 - 0.05^(1/n), about 3 / n). Drawn without replacement from a finite table the bound only
  errs on the safe side.

The record depends only on the table and the spec (no times, no counts of jobs), so a resumed
run writes the same record as an uninterrupted one, whatever --jobs.
"""
from __future__ import annotations

import math
import time
import warnings
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

import numpy as np

from fencesweep.errors import VerificationWarning
from fencesweep.kernel import numerics as NU
from fencesweep.study.store import table as store
from fencesweep.study.sweep import accuracy, compute, runs
from fencesweep.study.sweep import plan as PL
from fencesweep.study.sweep import sample as VS
from fencesweep.study.sweep.chunks import ChunkTables, tables_of

#: the re-run's step_factor, relative to the table's: tolerance TOL x step_factor^5 / 10
STEP_FACTOR_SCALE = 10 ** (-1 / NU.TOL_EXPONENT)
THRESHOLD = accuracy.AGREEMENT
WORST = 3  # scenes named in the record (the largest differences; the outcomes that differ)
#: the confidence of the bound on the share of rows over THRESHOLD
CONFIDENCE = 0.95


def planned_runs(n_models: int, n: int | None) -> int:
    """The runs a verification re-runs at most (the dry run's count): n, or the default size."""
    return VS.default_size(n_models) if n is None else min(int(n), n_models)


def tolerance(vals: dict) -> float:
    """The local error tolerance a run uses (model/prepare.py _numerics): TOL (IMPACT_TOL for a
    one-pulse scene) x step_factor^5, floored at TOL_MIN."""
    base = NU.IMPACT_TOL if vals["scene"] in ("impact", "freefall") else NU.TOL
    return max(base * float(vals["step_factor"]) ** NU.TOL_EXPONENT, NU.TOL_MIN)


def prepare() -> None:
    """Import what finishing a verification needs beyond the sweep (scipy.special, share_bound:
    ~0.1 s), so that a sweep can do it while its workers run the chunks (sweep/pipeline.py)."""
    import scipy.special  # noqa: F401


def early_rows(plan: PL.Plan, n: int | None = None) -> list:
    """The runs (by their first scene) that the sample's random part (sample.choose) will most
    likely re-run, known before any chunk is: the first rows of the table's random draw, as many
    as the sample leaves to random rows once its extremes are chosen (sample.expected_random).
    A sweep re-runs them on its workers beside its chunks (sweep/pipeline.py); the sample is
    chosen as ever, after the chunks, and only its re-runs not done yet are run then."""
    rows = VS.random_rows(plan)[:VS.expected_random(plan, n)]
    return list(dict.fromkeys(int(r) for r in plan.first_row[plan.row_model[rows]]))


@dataclass
class Ahead:
    """What a sweep does for its verification while its chunks run (sweep/pipeline.py): the re-runs
    of early_rows begun on its workers (`rows`, and `results`, the function that gives them) and
    the extremes' scores added as the chunks arrive (`scored`)."""

    rows: set = field(default_factory=set)
    results: Callable[[], dict] = dict
    scored: VS.Scores | None = None


def begin(plan: PL.Plan, work: Path, n: int | None = None, jobs: int = 1, local: bool = True,
          scheduler: str | None = None, simulate: Callable | None = None, serial_below: float | None = None,
          per_run: float | None = None, pool=None, tables: ChunkTables | None = None,
          ahead: Ahead | None = None) -> Callable[[], dict]:
    """Start verifying a plan whose chunks are all in `work` (`tables`: as the sweep read them,
    sweep/chunks.py): choose the sample and, given `pool` (the sweep's workers, still running), submit
    its re-runs to it. Returns the function that finishes: it re-runs the sample unless the
    pool does (on `jobs` local processes, in this one when the work is small, or on Dask), reads
    the table's values, compares, and gives the record. Meanwhile the caller may work: a sweep
    writes its table's last blocks while the workers re-run (sweep/pipeline.py). `ahead`: what
    the sweep began with its chunks (Ahead): only the sample's rows not re-run yet are
    submitted now, and the re-runs done are compared while the others run."""
    ahead = ahead or Ahead()
    tables = tables_of(plan, work, tables)
    sample = VS.choose(plan, work, n, tables, ahead.scored)
    spec = plan.spec
    rows = [int(plan.first_row[m]) for m in sample.models]
    if pool is not None:
        first, rest = ahead.results, compute.submit_reruns(pool, [r for r in rows if r not in ahead.rows],
                                                           STEP_FACTOR_SCALE, jobs)
    else:
        def rest() -> dict:
            use = runs.local_jobs(jobs, (per_run or 1e-3) * VS.RERUN_COST * len(rows), serial_below) \
                if local and jobs > 1 else jobs
            return compute.rerun_scenes(spec, rows, STEP_FACTOR_SCALE, use, local, scheduler, simulate)
        first = dict

    def finish() -> dict:
        table = _table_values(plan, tables, sample.models)
        vals = [spec.resolve(i) for i in rows]
        found: dict = {}
        for reruns in (first(), None):  # the re-runs done already, then the others once they are
            reruns = rest() if reruns is None else reruns
            for m, i, v in zip(sample.models, rows, vals):
                if i in reruns and i not in found:
                    found[i] = _compare(spec.scene, table[m], reruns[i], _freefall(v, table[m]))
        found = [found[i] for i in rows]
        return _record(plan, sample, rows, vals, found) | {"random": _random_part(plan, sample, found)}

    return finish


def verify(plan: PL.Plan, work: Path, n: int | None = None, jobs: int = 1, local: bool = True,
           scheduler: str | None = None, simulate: Callable | None = None, serial_below: float | None = None,
           per_run: float | None = None, tables: ChunkTables | None = None) -> dict:
    """Verify a plan whose chunks are all in `work`: begin(...) without a pool, and finish at
    once; the record."""
    return begin(plan, work, n, jobs, local, scheduler, simulate, serial_below, per_run, None, tables)()


def _table_values(plan: PL.Plan, tables: ChunkTables, models: list) -> dict:
    """{model run: {result: its values}} of the table (a list per result for a stream: its
    cycles), from the chunks that the table is assembled from."""
    by_chunk: dict = {}
    for m in models:
        by_chunk.setdefault(m // plan.chunk_size, []).append(m)
    out = {}
    for c, ms in by_chunk.items():
        table = tables.read(c)
        local = [m - c * plan.chunk_size for m in ms]
        cols = {name: _rows(table.column(name).combine_chunks(), local) for name in table.column_names}
        for k, m in enumerate(ms):
            if cols["_model"][k] != m:
                raise RuntimeError(f"chunk {c} in {tables.work} does not hold the runs it should; rerun with --no-resume")
            out[m] = {name: values[k] for name, values in cols.items() if name != "_model"}
    return out


def _rows(col, rows: list) -> list:
    """The values of rows `rows` of a chunk's column (a list per row for a stream's cycle
    results); read from Arrow's buffers (store.numpy_column), as take() would import pandas."""
    import pyarrow as pa

    if pa.types.is_list(col.type):
        return [list(store.numpy_column(col[r].values)) for r in rows]
    return list(store.numpy_column(col)[rows])


def _freefall(vals: dict, row: dict) -> float:
    """The scene's free-fall force [N] (docs/model.md §7), the scale of its force floors: the table's
    column for a cycle, computed for an impact (the free fall's is its own peak force)."""
    if "freefall_force" in row:
        values = [x for x in np.atleast_1d(row["freefall_force"]) if x is not None and math.isfinite(x)]
        return float(values[0]) if values else math.nan
    if vals["scene"] == "freefall":
        return float(row["peak_force"]) if row["peak_force"] is not None else math.nan
    from fencesweep.model.prepare import freefall_force

    try:
        return freefall_force(float(vals["m1"]), float(vals["k1"]), float(vals["e"]), vals["contact_law"],
                              vals["k_lin"], float(vals["H"]))
    except Exception:  # a scene the engine cannot run: its force floor is not known
        return math.nan


def _cycles(row: dict, name: str) -> list:
    value = row.get(name)
    return list(value) if isinstance(value, (list, tuple, np.ndarray)) else [value]


def _number(x) -> float:
    return math.nan if x is None else float(x)


def _compare(scene: str, table: dict, rerun: dict, freefall: float) -> dict:
    """One run against its re-run: outcome (None: they agree, else (cycle, table's, re-run's)),
    per result its largest difference (difference, cycle, table's, re-run's) over the cycles
    whose outcomes agree, and the results defined in only one of the two."""
    a, b = _cycles(table, "outcome"), _cycles(rerun, "outcome")
    agree = [k for k in range(min(len(a), len(b))) if a[k] == b[k]]
    differ = [k for k in range(max(len(a), len(b))) if k not in agree]
    out = {"outcome": (differ[0], a[differ[0]] if differ[0] < len(a) else None,
                       b[differ[0]] if differ[0] < len(b) else None) if differ else None,
           "diffs": {}, "undefined": []}
    for q in accuracy.QUANTITIES[scene]:
        ta, tb = _cycles(table, q), _cycles(rerun, q)
        worst = None
        for k in agree:
            x, y = _number(ta[k]), _number(tb[k])
            if math.isnan(x) and math.isnan(y):
                continue
            d = accuracy.relative_difference(x, y, q, freefall)
            if not math.isfinite(d):
                out["undefined"].append(q)
                break
            if worst is None or d > worst[0]:
                worst = (d, k, x, y)
        if worst is not None:
            out["diffs"][q] = worst
    return out


def share_bound(k: int, n: int, confidence: float = CONFIDENCE) -> float:
    """One-sided upper confidence bound on a share p from k of n draws over (Clopper & Pearson
    1934): the p at which k or fewer of n would be seen with probability 1 - confidence, the
    `confidence` quantile of Beta(k + 1, n - k); 1 when k = n or nothing was drawn."""
    if n <= 0 or k >= n:
        return 1.0
    from scipy.special import betaincinv

    return float(betaincinv(k + 1, n - k, confidence))


def _over(f: dict) -> bool:
    """Is a re-run's comparison over: a difference above THRESHOLD, a result defined in one of the
    two only, or an outcome that differs?"""
    return (f["outcome"] is not None or bool(f["undefined"])
            or any(d[0] > THRESHOLD for d in f["diffs"].values()))


def _random_part(plan: PL.Plan, sample: VS.Sample, found: list) -> dict:
    """The rows drawn uniformly (sweep/sample.py), how many of them are over, and the bound on
    the share of the table's rows that are (share_bound)."""
    over_model = {m: _over(f) for m, f in zip(sample.models, found)}
    k = sum(over_model[int(plan.row_model[r])] for r in sample.random_rows)
    n = len(sample.random_rows)
    return {"n": n, "over": int(k), "of_rows": int((plan.row_model >= 0).sum()), "threshold": THRESHOLD,
            "confidence": CONFIDENCE, "share_over_bound": share_bound(k, n),
            "method": "Clopper-Pearson, one-sided"}


def _plain(x):
    """A number for JSON: a finite float or int, else None."""
    if isinstance(x, (int, np.integer)) and not isinstance(x, bool):
        return int(x)
    x = _number(x)
    return x if math.isfinite(x) else None


def _span(values: list):
    """One value, or [smallest, largest] when they differ."""
    lo, hi = min(values), max(values)
    return lo if lo == hi else [lo, hi]


def _quantities(scene: str, rows: list, found: list) -> dict:
    out = {}
    for q in accuracy.QUANTITIES[scene]:
        hits = [(f["diffs"][q][0], i) for f, i in zip(found, rows) if q in f["diffs"]]
        d, i = max(hits, key=lambda h: (h[0], -h[1])) if hits else (None, None)
        out[q] = {"max_rel_diff": _plain(d), "scene": i, "floor": accuracy.floor_text(q),
                  "undefined": sum(q in f["undefined"] for f in found)}
    return out


def _worst(spec, rows: list, found: list) -> list:
    """The WORST runs by their largest difference: scene, label, result, difference, values."""
    per = []
    for f, i in zip(found, rows):
        if f["diffs"]:
            q, (d, k, x, y) = max(f["diffs"].items(), key=lambda kv: kv[1][0])
            per.append((d, i, q, k, x, y))
    per.sort(key=lambda r: (-r[0], r[1]))
    out = []
    for d, i, q, k, x, y in per[:WORST]:
        entry = {"scene": i, "label": spec.describe(i), "quantity": q, "rel_diff": _plain(d), "table": _plain(x),
                 "rerun": _plain(y)}
        out.append(entry | ({"cycle": k} if spec.scene == "stream" else {}))
    return out


def _outcomes(spec, rows: list, found: list) -> list:
    out = []
    for f, i in zip(found, rows):
        if f["outcome"] is not None and len(out) < WORST:
            k, a, b = f["outcome"]
            entry = {"scene": i, "label": spec.describe(i), "table": a, "rerun": b}
            out.append(entry | ({"cycle": k} if spec.scene == "stream" else {}))
    return out


def _record(plan: PL.Plan, sample: VS.Sample, rows: list, vals: list, found: list) -> dict:
    """The verification's record (the table's `fencesweep.verify`): plain JSON, no times."""
    spec = plan.spec
    quantities = _quantities(spec.scene, rows, found)
    mismatches = sum(f["outcome"] is not None for f in found)
    over = any((v["max_rel_diff"] or 0.0) > THRESHOLD or v["undefined"] for v in quantities.values())
    tol = [tolerance(v) for v in vals]
    tol_rerun = [tolerance(dict(v, step_factor=float(v["step_factor"]) * STEP_FACTOR_SCALE)) for v in vals]
    return {
        "n": len(rows), "of": plan.n_models,
        "sample": {"rule": (f"requested: {sample.target} runs" if sample.requested else
                            f"default: max({VS.MIN_RUNS}, {VS.SHARE:.0%} of the model runs), re-runs costing at most "
                            f"{VS.COST_SHARE:.0%} of the table's steps"),
                   "extremes": sample.n_extremes, "random": len(rows) - sample.n_extremes, "capped": sample.capped,
                   "extreme_scenes": {k: int(plan.first_row[m]) for k, m in sample.extremes.items()}},
        "cost": {"measure": "integrator steps (n_steps)", "table_steps": sample.total_steps,
                 "sample_steps": sample.steps,
                 "rerun_share": round(sample.steps * VS.RERUN_COST / max(sample.total_steps, 1), 5)},
        "tolerance": {"table": _span(tol), "rerun": _span(tol_rerun)},
        "step_factor_scale": STEP_FACTOR_SCALE,
        "quantities": quantities,
        "outcome_mismatches": mismatches,
        "outcomes_differ": _outcomes(spec, rows, found),
        "worst": _worst(spec, rows, found),
        "threshold": THRESHOLD,
        "ok": not over and mismatches == 0,
    }


def run_verification(plan: PL.Plan, work: Path, n: int | None, jobs: int, local: bool, scheduler: str | None,
                     simulate: Callable | None, serial_below: float | None, per_run: float | None,
                     tables: ChunkTables | None = None) -> tuple:
    """verify(...) and the seconds it took."""
    t = time.perf_counter()
    record = verify(plan, work, n, jobs, local, scheduler, simulate, serial_below, per_run, tables)
    return record, time.perf_counter() - t


def _fmt(x) -> str:
    return "n/a" if x is None else f"{x:.1g}"


def summary_line(record: dict) -> str:
    """The record in one line, e.g. 'verified 131 of 13122 runs at tol/10: max rel. difference
    peak_force 3e-06, ...; outcomes all agree'."""
    qs = ", ".join(f"{q} {_fmt(v['max_rel_diff'])}" for q, v in record["quantities"].items())
    k = record["outcome_mismatches"]
    agree = "outcomes all agree" if not k else f"{k} outcome{'s differ' if k > 1 else ' differs'}"
    capped = "; the cost cap left out some runs" if record["sample"]["capped"] else ""
    return (f"verified {record['n']} of {record['of']} runs at tol/10: max rel. difference {qs}; {agree}{capped}"
            f"{bound_text(record)}")


def bound_text(record: dict) -> str:
    """'; at most 2.3 % of rows over 1e-3, 95 % confidence (0 of 130 random rows over)', or
    nothing for a record without a random part."""
    r = record.get("random")
    if not r or not r["n"]:
        return ""
    pct = 100 * r["share_over_bound"]
    return (f"; at most {pct:.2g} % of rows over {r['threshold']:g}, {100 * r['confidence']:.0f} % confidence "
            f"({r['over']} of {r['n']} random rows over)")


def warning_lines(record: dict) -> list:
    """What a failed verification says (nothing when it is ok)."""
    if record["ok"]:
        return []
    out, names = [], {w["scene"]: w["label"] for w in record["worst"]}
    for q, v in record["quantities"].items():
        d = v["max_rel_diff"]
        if d is not None and d > THRESHOLD:
            where = names.get(v["scene"], f"scene #{v['scene']}")
            out.append(f"warning: verification failed: {q} differs by {d:.2g} (> {THRESHOLD:g}) from a re-run at "
                       f"tol/10 in {where}; the table's {q} is not converged to {THRESHOLD:g} there")
        if v["undefined"]:
            out.append(f"warning: verification failed: {q} is defined in only one of the table and its re-run at "
                       f"tol/10 in {v['undefined']} run(s)")
    for o in record["outcomes_differ"]:
        out.append(f"warning: verification failed: {o['label']}{' cycle ' + str(o['cycle']) if 'cycle' in o else ''} "
                   f"is {o['table']} in the table but {o['rerun']} at tol/10 ({record['outcome_mismatches']} of "
                   f"{record['n']} re-runs differ in outcome)")
    out.append("warning: the table's metadata key fencesweep.verify records the worst scenes (sweeps/README.md, "
               "Verification)")
    return out


def warn(record: dict) -> None:
    """Issue the warning lines of a failed verification as one VerificationWarning."""
    lines = [line.removeprefix("warning: ") for line in warning_lines(record)]
    if lines:
        warnings.warn("\n".join(lines), VerificationWarning, stacklevel=3)
