"""REPORT.md's opening: the element to build, right under the title, so that a reader who stops
after a few lines has the answer. It is the design over the load envelope (results/design/
recommended.json, written by `fencesweep design sweeps/envelope.yaml`): the element, its margins
to each constraint and the binding one, and what it was checked on (the envelope's loads it was
searched on, the fresh verification loads of design/verify_loads.parquet, the same loads back to
back from design/comparison.parquet). The elements of section 2 (the two-case pick and the
well-damped pick, read off the two named loads' maps) and the other compared elements follow as
comparisons on the same loads. Every number is read from those files; nothing is typed in here.
"""
from __future__ import annotations

import json
import math
from pathlib import Path

#: what the objectives of the design search choose (recommended.json's "objective")
GOAL = {"max_min_margin": "the element farthest inside every constraint",
        "min_worst_overload": "the least worst overload among the elements that keep every constraint"}


def _num(x) -> float | None:
    try:
        x = float(x)
    except (TypeError, ValueError):
        return None
    return None if math.isnan(x) else x


def _comparison(res: Path, rec: dict) -> list[dict]:
    """The compared elements on the verification loads: design/comparison.parquet, or the copy in
    recommended.json when the table is not there."""
    path = res / "design" / "comparison.parquet"
    if path.exists():
        import pandas as pd

        return pd.read_parquet(path).to_dict("records")
    return list(rec.get("comparison") or [])


def _is_element(row: dict, b2: float, k2: float) -> bool:
    """Whether a compared row is the flexible element b2 / k2 (a row's drive is empty for the
    design's own drive)."""
    drive = row.get("drive")
    if isinstance(drive, str) and drive != "flexible":
        return False
    rb, rk = _num(row.get("B2")), _num(row.get("K2"))
    return rb is not None and rk is not None and math.isclose(rb, b2) and math.isclose(rk, k2)


def _limit_text(rec: dict, name: str, res: Path) -> tuple[str, str]:
    """(worst, limit) of one constraint as text, in degrees for angles. A limit named by a parameter
    (deflection_max <= dalpha_perm) is read off the verification loads' table, which carries it per
    load; without that table it follows from the margin's definition, limit = worst / (1 - margin)."""
    worst = rec["worst"][f"worst_{name}"]
    limit = rec["constraints"][name]
    if isinstance(limit, str):
        per = res / "design" / "verify_loads.parquet"
        col = None
        if per.exists():
            import pandas as pd

            col = pd.read_parquet(per)
            col = col[limit].min() if limit in col else None
        limit = float(col) if col is not None else worst / (1.0 - rec["margins"][name])
    if rec["units"].get(name) == "rad":
        return f"{math.degrees(worst):.2f} deg", f"{math.degrees(limit):.3g} deg"
    return f"{worst:.3f}", f"{limit:g}"


def _margins(rec: dict, res: Path, row: dict | None) -> str:
    parts = []
    for name, m in rec["margins"].items():
        if m is None:  # scraped: a count, not a margin
            if row is not None:
                n = int(row["n_loads"])
                parts.append(f"{name} {int(round(row['share_scraped'] * n))} of {n} loads")
            continue
        worst, limit = _limit_text(rec, name, res)
        parts.append(f"{name} {m:.3f} (worst {worst}, limit {limit})")
    return "; ".join(parts)


def _checked_on(rec: dict, res: Path, row: dict | None) -> str:
    smp, ver = rec["optimisation_sample"], rec["verification"]
    text = (f"searched on {smp['n_loads']} loads of the envelope ({_dims_text(rec)}; smallest margin "
            f"{smp['min_margin']:.3f}), verified on {ver['n_loads']} fresh ones ({ver['method'].capitalize()} "
            f"sample, seed {ver['seed']}, "
            f"{ver.get('n_skipped', 0)} skipped; smallest margin {ver['min_margin']:.3f}; "
            "[`design/verify_loads.parquet`](design/verify_loads.parquet))")
    per = res / "design" / "verify_loads.parquet"
    if per.exists() and row is not None:
        import pandas as pd

        mine = pd.read_parquet(per, columns=["design", "status"])
        mine = mine[mine["design"] == row["design"]]
        ok = int((mine["status"] == "ok").sum())
        text += f"; {ok} of {len(mine)} of its verification runs ended with status ok"
    if row is not None and _num(row.get("stream_n_cycles")) is not None:
        n = int(row["stream_n_cycles"])
        text += (f". The same {n} loads back to back, one per work cycle at period {row['stream_period']:g} s: "
                 f"{'safe' if row['stream_safe'] else 'NOT safe'} ({int(row['stream_n_scraped'])} of {n} scraped, "
                 f"worst overload {row['stream_worst_overload']:.3f}, largest start amplitude "
                 f"{math.degrees(row['stream_worst_start_amplitude']):.2f} deg)")
    return text


def _versus(row: dict, ours: dict | None, what: str) -> str:
    """One compared element against the element to build, on the same loads."""
    against = (lambda k, f: f" against {ours[k]:{f}}") if ours is not None else (lambda k, f: "")
    if row["feasible"]:
        verdict = (f"keeps every constraint too, smallest margin {row['min_margin']:+.3f}"
                   f"{against('min_margin', '+.3f')} ({row['binding']} binding)")
    else:
        verdict = f"breaks {row['binding']} (smallest margin {row['min_margin']:+.3f})"
    return f"{what}: {verdict}; worst overload {row['worst_overload']:.3f}{against('worst_overload', '.3f')}"


def _comparisons(rows: list[dict], mine: dict | None, picks: dict) -> list[str]:
    """The compared elements, the picks of section 2 first and named as such; `picks`:
    (name, why) -> (B2, K2)."""
    named, rest = [], []
    for row in rows:
        if row is mine:
            continue
        hit = next(((name, why) for (name, why), (b2, k2) in picks.items() if _is_element(row, b2, k2)), None)
        if hit:
            named.append("* " + _versus(row, mine, f"{hit[0]} {row['B2']:g}/{row['K2']:g} ({hit[1]})"))
        else:
            rest.append("* " + _versus(row, mine, row["design"]))
    return named + rest


def _dims_text(rec: dict) -> str:
    """The envelope's ranges in a few words: 'L 0.2-0.7 m, ..., dP anywhere across the belt'."""
    from fencesweep.model.params import BY_NAME
    from fencesweep.study.spec import envelope as E

    parts = []
    for name, d in rec["envelope"]["dims"].items():
        unit = BY_NAME[name].unit if name in BY_NAME else ""
        unit = "" if unit in ("", "-") else f" {unit}"
        if isinstance(d, dict):
            parts.append(f"{name} {d['min']:g}-{d['max']:g}{unit}")
        elif d == E.ACROSS:
            parts.append(f"{name} anywhere across the belt")
        elif isinstance(d, list):
            parts.append(f"{name} one of {', '.join(map(str, d))}{unit}")
        elif d:
            parts.append(f"{name} = {d:g}{unit}")
    return ", ".join(parts)


def _working_point(rec: dict) -> dict:
    """What the design held fixed, with t_c and v from the parameters' defaults where the spec left
    them (the cycle then ran at those)."""
    from fencesweep.model.params import BY_NAME

    fixed = dict(rec.get("fixed") or {})
    for name in ("t_c", "v"):
        fixed.setdefault(name, BY_NAME[name].default)
    return fixed


def _fixed_text(name: str, value) -> str:
    """'drive flexible', 't_c = 1.36 s': what the design held fixed, with the parameter's unit."""
    if isinstance(value, str):
        return f"{name} {value}"
    from fencesweep.model.params import BY_NAME

    unit = BY_NAME[name].unit if name in BY_NAME else ""
    return f"{name} = {value:g}" + ("" if unit in ("", "-") else f" {unit}")


def answer_lines(res: Path, D=None) -> list[str]:
    """The report's opening lines (empty when `fencesweep design` has not run). `D`: the two named
    loads' design maps (fencesweep.report.analysis.Design), whose picks are named in the comparison."""
    res = Path(res)
    path = res / "design" / "recommended.json"
    if not path.exists():
        return []
    rec = json.loads(path.read_text())
    dv, units = rec["design_variables"], rec["units"]
    rows = _comparison(res, rec)
    b2, k2 = float(dv["B2"]), float(dv["K2"])
    mine = next((r for r in rows if _is_element(r, b2, k2)), None)
    element = ", ".join(f"{k} = {v:g} {units.get(k, '')}".rstrip() for k, v in dv.items())
    fixed = ", ".join(_fixed_text(k, v) for k, v in _working_point(rec).items())
    goal = GOAL.get(rec["objective"], rec["objective"])
    if not str(rec["status"]).startswith("feasible"):  # "feasible", or "feasible (<the search's note>)"
        return [f"**No element keeps every constraint over the load envelope** (design status: {rec['status']}; "
                f"section 7, [`design/recommended.json`](design/recommended.json)). The search's best, {element} "
                f"({fixed}), has margins {_margins(rec, res, mine)}; binding: {rec['worst']['binding']}.", ""]
    n = rec["verification"]["n_loads"]
    L = [f"**The element to build: {element}** ({fixed}): the design over the load envelope of section 7, "
         f"{goal} for every load (`fencesweep design {rec.get('spec_path', '')}`, status {rec['status']}; "
         "[`design/recommended.json`](design/recommended.json)).", "",
         f"* Margins (1 - worst / limit) over the {n} verification loads: {_margins(rec, res, mine)}. "
         f"**Binding: {rec['worst']['binding']}.**",
         f"* Checked on: {_checked_on(rec, res, mine)}."]
    picks = {}
    if D is not None and D.best:
        picks[("the two-case pick", "section 2: the least overload for the two named loads alone")] = \
            (D.best["B2"], D.best["K2"])
    if D is not None and D.damped:
        picks[("the well-damped pick", "section 2: the same with 0.7 <= Psi <= 1")] = (D.damped["B2"], D.damped["K2"])
    others = _comparisons(rows, mine, picks)
    if others:
        L += ["", f"Compared with it on the same {n} loads (section 7's table, "
              "[`design/comparison.parquet`](design/comparison.parquet)):", *others]
    return L + [""]
