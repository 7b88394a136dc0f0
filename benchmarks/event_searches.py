"""How many evaluations does locating a contact change take? On the main job's fixed sample of 60
scenes, every event that find_event locates (a slot changing its code, side or tip's edge inside a
step): the evaluations of the bisection's predicate (events.mask_changed: the dense output, the
frame and the whole manifold, ~1,200 instructions) and of the margin that brackets it first
(events.margin_at, ~500), by the slot whose margin was used and by what changed.

    python benchmarks/event_searches.py [--rev REV ...] [--out FILE]   -> prints, writes --out (markdown)

Each tree (this one, and each REV exported by `git archive`) runs in a fresh process with Numba's
JIT off (NUMBA_DISABLE_JIT=1: the kernels as plain Python, whose searches are the compiled ones'
step for step), the predicate and the margin wrapped to count their calls, and events.locate_change
wrapped to read, at the end of each search, which slots changed (slots.classify_in there against
the step's start). Counts, not time: ~10 s a tree.
"""
from __future__ import annotations

import argparse
import collections
from pathlib import Path

from common import ROOT, export, md_table, run_json

WORKER = r"""
import collections, json, os, sys
import numpy as np
import fencesweep
from fencesweep.model.scenes.cycle import events as E, slots as S
from fencesweep.model.scenes.contacts import N_SLOTS
from fencesweep.model.scenes.cycle.layout import IW_CODE, N_CTRL
calls = collections.Counter()
def counting(fn, what):
    def wrapped(ctx, theta):
        calls[what] += 1
        return fn(ctx, theta)
    return wrapped
pred = counting(E.mask_changed, "pred")
E.find_change.__globals__["PRED"] = pred
E.mask_changed = pred
if hasattr(E, "check_change"):
    E.check_change.__globals__["PRED"] = pred
if hasattr(E, "margin_at"):
    q = counting(E.margin_at, "margin")
    E.find_margin.__globals__["QUANTITY"] = q
    E.margin_at = q
kinds = collections.defaultdict(lambda: [0, 0, 0])
def counted(*args):  # locate_change(t, h, y0, Q, p, iw, tmp, ...), or an older tree's find_change(ctx, ...)
    t, h, y0, Q, p, iw, tmp = args[:7] if len(args) == 12 else args[0][:7]
    k = args[10] if len(args) == 12 else -1
    before = dict(calls)
    out = search(*args)
    E.rk.dense_eval(y0, Q, out[1], tmp, N_CTRL)
    codes, tags = np.zeros(N_SLOTS, np.int64), np.zeros(N_SLOTS, np.int64)
    S.classify_in(tmp, p, iw, codes, np.zeros(N_SLOTS), np.zeros(N_SLOTS), tags, *S.frame_at(t + out[1] * h, tmp, p, iw))
    changed = " ".join(f"{j}:{'APC'[iw[IW_CODE + j]]}{'APC'[codes[j]]}" if codes[j] != iw[IW_CODE + j] else f"{j}:side/edge"
                       for j in range(N_SLOTS) if S.slot_changed(j, codes[j], tags[j], iw))
    row = kinds[(int(k), changed or "(none at the end)")]
    row[0] += 1
    row[1] += calls["pred"] - before.get("pred", 0)
    row[2] += calls["margin"] - before.get("margin", 0)
    return out
if hasattr(E, "locate_change"):
    search, E.locate_change = E.locate_change, counted
else:  # before the margins (496dde5 and older): find_event bisects with find_change itself
    search, E.find_change = E.find_change, counted
b2, k2 = np.linspace(0, 200, 81), np.linspace(100, 2100, 81)
for i in np.random.default_rng(20261123).choice(81 * 81 * 2, 60, replace=False):
    fencesweep.simulate("cycle", ("small_far", "long_near")[i // 6561], B2=float(b2[i % 6561 // 81]), K2=float(k2[i % 81]))
print(json.dumps([[k, c, *v] for (k, c), v in kinds.items()]))
"""


def count(tree: Path) -> list:
    """[slot whose margin bracketed (-1 none), what changed, events, predicate calls, margin calls]."""
    return run_json(WORKER, env={"PYTHONPATH": str(tree), "NUMBA_DISABLE_JIT": "1"}, cwd=tree)


def page(trees: dict) -> list[str]:
    lines = ["# Locating a contact change: evaluations an event", "",
             "Regenerate: `python benchmarks/event_searches.py --rev REV --out FILE` (its docstring says what it "
             "counts). The main job's fixed sample of 60 scenes, one cycle each. Slots: corners on the fence 0-3, "
             "on the rail 4-7, TIP 8, PIVOT 9; codes A(part), P(ush), C(lipped).", ""]
    lines += md_table(["tree", "events>", "predicate calls>", "an event>", "margin calls>", "an event>"],
                      [[name, f"{sum(r[2] for r in rows):,}", f"{sum(r[3] for r in rows):,}",
                        f"{sum(r[3] for r in rows) / max(1, sum(r[2] for r in rows)):.1f}",
                        f"{sum(r[4] for r in rows):,}", f"{sum(r[4] for r in rows) / max(1, sum(r[2] for r in rows)):.1f}"]
                       for name, rows in trees.items()])
    name, rows = list(trees.items())[-1]
    by = collections.defaultdict(lambda: [0, 0, 0])
    for k, what, n, pr, mg in rows:
        b = by[(k, what)]
        b[0] += n
        b[1] += pr
        b[2] += mg
    lines += ["", f"{name}, by event (the most predicate calls first):", ""]
    lines += md_table(["margin of slot>", "what changed", "events>", "predicate calls>", "margin calls>"],
                      [[k if k >= 0 else "none", what, n, pr, mg]
                       for (k, what), (n, pr, mg) in sorted(by.items(), key=lambda kv: -kv[1][1])])
    return lines


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rev", nargs="*", default=[], help="earlier revisions to count beside this tree")
    ap.add_argument("--out", type=Path, help="write the page here (markdown)")
    a = ap.parse_args()
    trees = {rev: count(export(rev)) for rev in a.rev}
    trees["this tree"] = count(ROOT)
    text = "\n".join(page(trees)) + "\n"
    print(text)
    if a.out:
        a.out.write_text(text)


if __name__ == "__main__":
    main()
