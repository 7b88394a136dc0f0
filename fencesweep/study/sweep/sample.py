"""Which runs a sweep's verification re-runs (sweep/verify.py): a sample of its distinct model runs,
read from the finished chunks, the extremes first, then random; the same for the same table
(whatever --jobs, backend or interruptions).

* Size: max(MIN_RUNS, SHARE of the model runs), at most all of them; `--verify N`: N.
* Extremes (EXTREMES): for each criterion the most extreme run (the highest peak_force, the
  overload closest to 1, the most steps, the shallowest contact, ...), criterion after
  criterion, then the next most extreme of each, until half the sample (at least the first of
  every criterion) is chosen; a criterion that no run meets (no rail contact at all) is passed.
  A stream's run is judged by its worst cycle (its steps: all its cycles').
* Random: the rest, rows of the table drawn uniformly without replacement (a permutation
  seeded by the spec's hash), each re-run through its model run (a run already chosen is not
  run twice, but its row still counts as drawn). The extremes find the large errors; the
  random rows bound the share of rows that the re-runs did not see (sweep/verify.py, the bound).
* Cost: counted in the table's integrator steps (n_steps, deterministic, unlike time), a
  re-run costing RERUN_COST times its steps (steps scale like 1 / step_factor). The default
  sample takes extremes while the re-runs cost at most COST_SHARE of the table's steps,
  skipping one that would exceed it, then random rows until the next would exceed it (a
  random draw is never skipped for its cost: that would favour cheap rows); the first
  MIN_RUNS are always taken (a sweep that small costs little). An explicit N is not capped.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from fencesweep.kernel import numerics as NU
from fencesweep.study.store import table as store
from fencesweep.study.sweep import plan as PL
from fencesweep.study.sweep.chunks import ChunkTables, tables_of

MIN_RUNS = 16  # the fewest runs a default sample re-runs
SHARE = 0.01  # ... or this share of the model runs, whichever is more
COST_SHARE = 0.05  # a default sample's re-runs cost at most this share of the table's steps
#: a re-run at tol / 10 takes about 10^(1/5) = 1.58 times the steps (DOPRI5's steps scale like
#: tol^(1/5); RK4's dt is scaled by the same factor); measured on the main job: 1.42
RERUN_COST = 10 ** (1 / NU.TOL_EXPONENT)

#: (criterion, columns it reads); cycle and stream scenes, then impact and freefall
EXTREMES = {
    "cycle": (("highest peak_force", ("peak_force",)), ("highest overload", ("overload",)),
              ("largest deflection_max", ("deflection_max",)), ("overload closest to 1", ("overload",)),
              ("deflection_max closest to dalpha_perm", ("deflection_max",)), ("most steps", ("n_steps",)),
              ("most rejected steps", ("n_rejected",)),
              ("shallowest fence contact", ("t_first_contact", "max_penetration")),
              ("weakest rail contact", ("peak_rail_force",))),
    "impact": (("highest peak_force", ("peak_force",)), ("lowest peak_force", ("peak_force",)),
               ("deepest penetration", ("max_penetration",)), ("shortest contact", ("contact_time",)),
               ("most steps", ("n_steps",))),
}


def kind(scene: str) -> str:
    return "cycle" if scene in ("cycle", "stream") else "impact"


@dataclass
class Sample:
    """The runs to re-run, in the order chosen, and why."""

    models: list  # model run numbers
    extremes: dict = field(default_factory=dict)  # criterion -> the model run it chose first
    n_extremes: int = 0
    target: int = 0  # the size asked for (the cost cap may leave fewer)
    capped: bool = False  # the cost cap left out runs
    steps: int = 0  # the table's steps of the chosen runs
    total_steps: int = 0  # the table's steps of every model run
    requested: bool = False  # the size was asked for (--verify N), not the default
    random_rows: list = field(default_factory=list)  # the rows drawn uniformly, in order (scene numbers)


def default_size(n_models: int) -> int:
    """max(MIN_RUNS, SHARE x the runs), at most all of them."""
    return min(n_models, max(MIN_RUNS, math.ceil(SHARE * n_models)))


def _cycles(table, names: list) -> tuple:
    """A chunk's columns `names` as flat arrays over its runs' cycles (a stream's run holds a
    list per result: one entry per cycle) and the run (row of the chunk) of each entry."""
    import pyarrow as pa

    cols, owner = {}, None
    for name in names:
        col = table.column(name).combine_chunks()
        if pa.types.is_list(col.type):
            import pyarrow.compute as pc  # a stream's only: its import takes ~30 ms

            owner = store.numpy_column(pc.list_parent_indices(col)) if owner is None else owner
            col = col.flatten()
        cols[name] = store.numpy_column(col).astype(float)
    return cols, (np.arange(table.num_rows) if owner is None else owner)


def _cycle_scores(cols: dict, dalpha: np.ndarray) -> dict:
    """Per criterion of a cycle, a score per cycle: the smallest is the most extreme (inf: not met)."""
    with np.errstate(invalid="ignore", divide="ignore"):
        contact = np.isfinite(cols["t_first_contact"]) & (cols["max_penetration"] > 0)
        return {"highest peak_force": -cols["peak_force"], "highest overload": -cols["overload"],
                "largest deflection_max": -cols["deflection_max"],
                "overload closest to 1": np.abs(cols["overload"] - 1.0),
                "deflection_max closest to dalpha_perm": np.abs(cols["deflection_max"] / dalpha - 1.0),
                "shallowest fence contact": np.where(contact, cols["max_penetration"], np.inf),
                "weakest rail contact": np.where(cols["peak_rail_force"] > 0, cols["peak_rail_force"], np.inf)}


def _impact_scores(cols: dict) -> dict:
    """Per criterion of an impact (or a free fall), a score per run."""
    return {"highest peak_force": -cols["peak_force"],
            "lowest peak_force": np.where(cols["peak_force"] > 0, cols["peak_force"], np.inf),
            "deepest penetration": -cols["max_penetration"],
            "shortest contact": np.where(cols["contact_time"] > 0, cols["contact_time"], np.inf)}


STEPS = ("most steps", "most rejected steps")


def _columns(scene: str) -> list:
    return sorted({c for _, names in EXTREMES[kind(scene)] for c in names})


class Scores:
    """The extremes' scores of a plan's runs (scores), added chunk by chunk: a sweep adds each
    chunk as it arrives, while its workers run the others (sweep/pipeline.py)."""

    def __init__(self, plan: PL.Plan):
        self.plan = plan
        self.names = _columns(plan.spec.scene)
        self.crit = {name: np.full(plan.n_models, np.inf) for name, _ in EXTREMES[kind(plan.spec.scene)]}
        self.steps = np.zeros(plan.n_models)
        self.dalpha = dalpha_perm(plan) if kind(plan.spec.scene) == "cycle" else None
        self.added: set = set()

    def add(self, c: int, tables: ChunkTables) -> None:
        """Score chunk `c`'s runs (once)."""
        if c in self.added:
            return
        self.added.add(c)
        table = tables.read(c, self.names + ["_model"])
        cols, owner = _cycles(table, self.names)
        model = store.numpy_column(table.column("_model"))[owner]
        runs = self.plan.chunk_models(c)  # the chunk's runs: scores go to crit[...][runs], run by run
        local, k, at = model - runs.start, len(runs), slice(runs.start, runs.stop)
        per = _cycle_scores(cols, self.dalpha[model]) if self.dalpha is not None else _impact_scores(cols)
        for name, score in per.items():
            best = np.full(k, np.inf)
            np.minimum.at(best, local, np.where(np.isnan(score), np.inf, score))
            self.crit[name][at] = np.minimum(self.crit[name][at], best)
        for name, col in zip(STEPS, ("n_steps", "n_rejected")):
            if col in cols:
                total = np.bincount(local, weights=np.nan_to_num(cols[col]), minlength=k)
                self.crit[name][at] = np.minimum(self.crit[name][at], np.where(total > 0, -total, np.inf))
        self.steps[at] += np.bincount(local, weights=np.nan_to_num(cols["n_steps"]), minlength=k)

    def result(self, tables: ChunkTables) -> tuple:
        """({criterion: score per model run}, the table's steps per model run), every chunk added."""
        for c in range(self.plan.n_chunks):
            self.add(c, tables)
        return self.crit, self.steps


def scores(plan: PL.Plan, work, tables: ChunkTables | None = None) -> tuple:
    """({criterion: score per model run}, the table's steps per model run), read from the chunks
    (`tables`: those the sweep read as they finished, sweep/chunks.py)."""
    return Scores(plan).result(tables_of(plan, work, tables))


def dalpha_perm(plan: PL.Plan) -> np.ndarray:
    """dalpha_perm of each model run, from the plan's columns (spec/scenes.py)."""
    return plan.columns().column("dalpha_perm", plan.first_row).astype(np.float64)


def choose(plan: PL.Plan, work, n: int | None = None, tables: ChunkTables | None = None,
           scored: Scores | None = None) -> Sample:
    """The sample of a plan whose chunks are all in `work` (and `tables`, scores; `scored`: the
    scores added so far): `n` runs (None: the default size, under the cost cap), the extremes
    first, then random (module docstring)."""
    tables = tables_of(plan, work, tables)
    crit, steps = (scored or Scores(plan)).result(tables)
    target = default_size(plan.n_models) if n is None else min(int(n), plan.n_models)
    order, extremes = _extremes(crit, target)
    cost = np.maximum(steps, 1.0)
    budget = COST_SHARE * cost.sum() / RERUN_COST if n is None else math.inf
    floor = min(MIN_RUNS, target) if n is None else target
    chosen, spent, seen = [], 0.0, set()
    for m in order:
        if len(chosen) == target:
            break
        if len(chosen) < floor or spent + cost[m] <= budget:
            seen.add(m)
            chosen.append(m)
            spent += cost[m]
    drawn = []
    for row in random_rows(plan):
        if len(chosen) == target:
            break
        m = int(plan.row_model[row])
        if m not in seen:
            if len(chosen) >= floor and spent + cost[m] > budget:
                break  # a random row is never skipped for its cost (module docstring)
            seen.add(m)
            chosen.append(m)
            spent += cost[m]
        drawn.append(int(row))
    taken, extreme = set(chosen), set(order)
    return Sample(chosen, {k: v for k, v in extremes.items() if v in taken}, len(taken & extreme), target,
                  len(chosen) < target, int(steps[chosen].sum()), int(steps.sum()), n is not None, drawn)


def _extremes(crit: dict, target: int) -> tuple:
    """The runs chosen as extremes, in order: the most extreme run not yet chosen of each
    criterion in turn, round after round, until half the target (at least one round); and the
    most extreme run of each criterion."""
    want = max(len(crit), target // 2) if target >= len(crit) else target
    ranked = {}
    for name, score in crit.items():
        k = min(len(score), want)
        top = np.argpartition(score, k - 1)[:k] if k < len(score) else np.arange(len(score))
        top = top[np.lexsort((top, score[top]))]  # by score, ties by run number
        ranked[name] = [int(m) for m in top if np.isfinite(score[m])]
    order, seen, pos = [], set(), dict.fromkeys(ranked, 0)
    while len(order) < want:
        before = len(order)
        for name, runs in ranked.items():
            while pos[name] < len(runs) and runs[pos[name]] in seen:
                pos[name] += 1
            if pos[name] < len(runs) and len(order) < want:
                seen.add(runs[pos[name]])
                order.append(runs[pos[name]])
        if len(order) == before:
            break
    return order, {name: runs[0] for name, runs in ranked.items() if runs}


def expected_random(plan: PL.Plan, n: int | None = None) -> int:
    """How many runs the random part of a sample of `n` runs (None: the default size) takes when
    its extremes fill their half (choose): the sample's size less the extremes wanted."""
    target = default_size(plan.n_models) if n is None else min(int(n), plan.n_models)
    n_crit = len(EXTREMES[kind(plan.spec.scene)])
    return target - (max(n_crit, target // 2) if target >= n_crit else target)


def random_rows(plan: PL.Plan) -> np.ndarray:
    """The table's random draw of rows (_random_rows), seeded by the spec's hash, as choose takes it."""
    return _random_rows(plan, int(plan.spec.hash[:16], 16))


def _random_rows(plan: PL.Plan, seed: int) -> np.ndarray:
    """The table's rows that have a model run (a skipped scene has none), in a random order
    (seeded): a uniform draw without replacement, read as far as the sample needs."""
    rows = np.nonzero(plan.row_model >= 0)[0]
    return rows[np.random.default_rng(seed).permutation(len(rows))]
