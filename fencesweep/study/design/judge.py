"""An envelope sweep's design points judged over their loads (docs/model.md §12): the worst
overload, deflection_max and residual_amplitude, which load is worst for each, the share scraped,
and the margin to each constraint (1 - worst / limit; negative when the constraint is broken).
`fencesweep grid` and `fencesweep design` both judge through `summarize`; a large table is judged
batch by batch (`partial`, `combine`, `finish`). Orchestration only: no physics here.
"""
from __future__ import annotations

import numpy as np

from fencesweep.study.spec.design import Limits
from fencesweep.study.spec.envelope import Envelope

#: the constraints' margins, in the order `binding` names them
MARGINS = ["margin_scraped", "margin_overload", "margin_deflection_max", "margin_residual_amplitude"]


def load_index(df, env: Envelope) -> np.ndarray:
    """The envelope load (index into env.loads) of each row of a per-load table (-1: none), on
    whole columns: each column's values numbered (np.unique), the numbers of a row combined into
    one, and only the distinct combinations looked up."""
    lookup = {k: i for i, k in enumerate(env.loads)}
    code, levels = np.zeros(len(df), dtype=np.int64), []
    for name in env.names:
        values, inverse = np.unique(df[name].to_numpy(), return_inverse=True)
        code = code * len(values) + inverse.ravel()
        levels.append(values)
    present, inverse = np.unique(code, return_inverse=True)
    found = np.empty(len(present), dtype=np.int64)
    for k, c in enumerate(present.tolist()):
        picks = []
        for values in reversed(levels):
            c, r = divmod(c, len(values))
            picks.append(_norm(values[r]))
        found[k] = lookup.get(tuple(reversed(picks)), -1)
    return found[inverse.ravel()]


def _norm(x):
    return x if isinstance(x, str) else float(x)


WORST = ("overload", "deflection_max", "residual_amplitude")


def partial(df, by: list, limits: Limits):
    """Per design point (the columns `by`) of some of its loads (rows of `df` with a `load` column):
    n_loads, n_scraped, worst_* and worst_*_load, dlim (the deflection limit). Partials of
    disjoint rows combine with `combine`: a table is judged batch by batch in flat memory."""
    import pandas as pd

    d = df.assign(_scraped=(df["outcome"] == "scraped").astype(np.int64),
                  _dlim=df["dalpha_perm"] if limits.deflection_max is None else limits.deflection_max,
                  _one=1)
    d["overload"] = d["overload"].fillna(0.0)  # no contact: no force
    g = d.groupby(by or (lambda _: 0), sort=False)
    out = pd.DataFrame({"n_loads": g["_one"].sum(), "n_scraped": g["_scraped"].sum(), "dlim": g["_dlim"].min()})
    for col in WORST:
        idx = g[col].idxmax().to_numpy()
        out[f"worst_{col}"] = d.loc[idx, col].to_numpy()
        out[f"worst_{col}_load"] = d.loc[idx, "load"].to_numpy()
    return out


def combine(parts: list):
    """Partials of disjoint rows of the same design points -> one partial."""
    import pandas as pd

    if len(parts) == 1:
        return parts[0]
    allp = pd.concat(parts)
    g = allp.groupby(level=list(range(allp.index.nlevels)), sort=False)
    out = pd.DataFrame({"n_loads": g["n_loads"].sum(), "n_scraped": g["n_scraped"].sum(), "dlim": g["dlim"].min()})
    flat = allp.reset_index(drop=True)
    keys = allp.index
    for col in WORST:
        idx = flat.groupby(np.asarray(pd.factorize(keys)[0]), sort=False)[f"worst_{col}"].idxmax().to_numpy()
        out[f"worst_{col}"] = flat.loc[idx, f"worst_{col}"].to_numpy()
        out[f"worst_{col}_load"] = flat.loc[idx, f"worst_{col}_load"].to_numpy()
    return out


def finish(part, by: list, limits: Limits):
    """A partial over all the loads -> the per-design-point table (see summarize)."""
    out = part.copy()
    out.insert(1, "share_scraped", out["n_scraped"] / out["n_loads"])
    out.insert(2, "n_escaped", out["n_loads"] - out["n_scraped"])
    # an escape is a broken constraint (share - 1 < 0); every load scraped leaves no finite margin
    out["margin_scraped"] = (np.where(out["share_scraped"] < 1.0, out["share_scraped"] - 1.0, np.inf)
                             if limits.scraped else np.inf)
    out["margin_overload"] = 1.0 - out["worst_overload"] / limits.overload
    out["margin_deflection_max"] = 1.0 - out["worst_deflection_max"] / out["dlim"]
    out["margin_residual_amplitude"] = (1.0 - out["worst_residual_amplitude"] / limits.residual_amplitude
                                        if limits.residual_amplitude is not None else np.inf)
    m = out[MARGINS]
    out["min_margin"] = m.min(axis=1)
    out["binding"] = m.idxmin(axis=1).str.removeprefix("margin_")
    out["feasible"] = out["min_margin"] >= 0.0
    out = out.drop(columns=["n_scraped", "dlim"])
    return out.reset_index(drop=not by)


def summarize(df, by: list, limits: Limits):
    """Per design point (the columns `by`) over its loads (rows of `df` with a `load` column):
    n_loads, share_scraped, n_escaped, worst_* and worst_*_load (the load index), margin_*
    (1 - worst / limit; for scraped, share_scraped - 1 when a load escapes, inf when none does),
    min_margin, binding (the constraint with the smallest margin) and feasible."""
    return finish(partial(df, by, limits), by, limits)


def spec_limits(spec) -> Limits:
    """The constraints of a spec's design section (defaults when it has none)."""
    design = getattr(spec, "design", None)
    return design.limits if design is not None else Limits()
