"""Result names, units and codes (docs/model.md §8, §9, §11): one table, used by the API,
the CLI and the Parquet store.

Kernels write results into a float64 vector at the indices below; `unpack` turns it into
a dict under the names of docs/model.md. Outcomes and statuses are integer codes with one table
of messages each.
"""
from __future__ import annotations

import math

import numpy as np

# ---- outcome codes (docs/model.md §9) ----
SCRAPED, ESCAPED, TIMEOUT, FAILED, JAMMED = 0, 1, 2, 3, 4
#: jammed (docs/model.md §14, `stream` only): the next cycle's load arrived with this one still on the belt
OUTCOMES = ("scraped", "escaped", "timeout", "failed", "jammed")

# ---- status codes: 0 ok, the rest name why a run cannot be trusted ----
ST_OK, ST_PENETRATION, ST_NONFINITE, ST_MAXSTEPS, ST_UNDERFLOW, ST_NOT_RUN = 0, 1, 2, 3, 4, 5
STATUS_MESSAGES = (
    "ok",
    "failed: penetration larger than half the load's smaller side (contact too soft or step too large)",
    "failed: non-finite state",
    "failed: step budget exhausted",
    "failed: step size underflow (the error tolerance cannot be met)",
    "failed: not run, an earlier cycle of the stream failed",
)

# ---- stages (docs/model.md §10) ----
STAGE_S1, STAGE_S2, STAGE_S3, STAGE_S4, STAGE_RAIL = 0, 1, 2, 3, 4

# ---- result vector layout for the cycle scene (docs/model.md §11), name -> (index, unit, meaning) ----
CYCLE_RESULTS = (
    ("outcome", "-", "scraped / escaped / timeout / failed"),
    ("t_exit", "s", "time of the outcome event"),
    ("peak_force", "N", "max over time of the summed load-fence normal forces"),
    ("peak_rail_force", "N", "max over time of the summed rail normal forces"),
    ("freefall_force", "N", "peak force of the same load dropped from H (docs/model.md §7)"),
    ("overload", "-", "peak_force / freefall_force"),
    ("safe", "-", "overload <= 1"),
    ("deflection_ok", "-", "deflection_max <= dalpha_perm"),
    ("deflection_max", "rad", "max |alpha - alpha_w| over [0, max(t_exit, t_c)]"),
    ("residual_deflection", "rad", "|alpha(t_c) - alpha_w(t_c)|"),
    ("residual_amplitude", "rad", "sqrt(dalpha(t_c)^2 + (dalpha'(t_c)/omega_n)^2), omega_n = sqrt(K2/I2)"),
    ("alpha_max", "rad", "largest fence angle over [0, max(t_exit, t_c)]"),
    ("damper_energy", "J", "integral of B2 (dalpha_w - dalpha)^2 over [0, t_c]"),
    ("contact_energy", "J", "energy lost in the contacts up to t_exit"),
    ("t_first_contact", "s", "A: first load-fence contact (NaN if none)"),
    ("contact_time", "s", "B - A for load-fence contacts"),
    ("n_impacts", "-", "load-fence contact onsets from a state with no load-fence contact"),
    ("t_S1", "s", "time in stage S1 (one fence contact point, no rail)"),
    ("t_S2", "s", "time in stage S2 (no contact)"),
    ("t_S3", "s", "time in stage S3 (two or more fence contact points, no rail)"),
    ("t_S4", "s", "time in stage S4 (fence and rail)"),
    ("t_rail", "s", "time with rail contact only"),
    ("x_exit", "m", "load centroid x at exit"),
    ("phi_exit", "rad", "load angle at exit"),
    ("max_penetration", "m", "largest penetration of any contact"),
    ("n_steps", "-", "integrator steps taken (accepted)"),
    ("n_rejected", "-", "steps rejected by the error control"),
    ("error_estimate", "-", "root-sum-square of the accepted steps' local error estimates, relative to the error scales"),
    ("status", "-", "ok, or failed and why"),
)
IMPACT_RESULTS = (
    ("peak_force", "N", "peak normal force"),
    ("impulse", "N s", "integral of the normal force over the contact"),
    ("contact_time", "s", "duration from onset to the first return of N to 0"),
    ("e_eff", "-", "rebound over approach normal speed, relative to the fence point"),
    ("max_penetration", "m", "largest penetration"),
    ("n_steps", "-", "integrator steps taken"),
    ("status", "-", "ok, or failed and why"),
)
FREEFALL_RESULTS = IMPACT_RESULTS
#: docs/model.md §14: a stream's cycle k has the results of §11 (times from t_k) and these
START_RESULTS = (
    ("start_deflection", "rad", "dalpha(t_k) = alpha - alpha_w at the cycle's start"),
    ("start_rate", "rad/s", "dalpha'(t_k) at the cycle's start"),
    ("start_amplitude", "rad", "sqrt(dalpha(t_k)^2 + (dalpha'(t_k)/omega_n)^2), the residual_amplitude formula at t_k"),
)
STREAM_CYCLE_RESULTS = CYCLE_RESULTS + START_RESULTS
#: docs/model.md §14: the results of the whole stream (results.stream_summary)
STREAM_RESULTS = (
    ("n_cycles", "-", "number of work cycles"),
    ("n_scraped", "-", "cycles whose outcome is scraped"),
    ("first_failure", "-", "index of the first cycle whose outcome is not scraped (-1 if none)"),
    ("worst_overload", "-", "largest overload of the cycles"),
    ("worst_deflection", "rad", "largest deflection_max of the cycles"),
    ("worst_start_amplitude", "rad", "largest start_amplitude of the cycles"),
    ("throughput", "1/h", "3600 / period: packages per hour"),
)

SCENE_RESULTS = {"cycle": CYCLE_RESULTS, "impact": IMPACT_RESULTS, "freefall": FREEFALL_RESULTS,
                 "stream": STREAM_CYCLE_RESULTS}

#: index of each cycle result in the kernel's output vector
RI = {name: i for i, (name, _, _) in enumerate(CYCLE_RESULTS)}
#: index of each impact/freefall result in the kernel's output vector
RJ = {name: i for i, (name, _, _) in enumerate(IMPACT_RESULTS)}
N_CYCLE_RESULTS = len(CYCLE_RESULTS)
N_STREAM_CYCLE_RESULTS = len(STREAM_CYCLE_RESULTS)
# compile-time constants for the kernels: RC_<NAME> (cycle), RJ_<NAME> (impact, freefall)
for _i, (_n, _u, _d) in enumerate(STREAM_CYCLE_RESULTS):
    globals()["RC_" + _n.upper()] = _i
for _i, (_n, _u, _d) in enumerate(IMPACT_RESULTS):
    globals()["RJ_" + _n.upper()] = _i
N_IMPACT_RESULTS = len(IMPACT_RESULTS)

UNITS = {name: unit for rows in SCENE_RESULTS.values() for name, unit, _ in rows}
UNITS.update({name: unit for name, unit, _ in STREAM_RESULTS})
_INT_RESULTS = {"n_impacts", "n_steps", "n_rejected", "n_cycles", "n_scraped", "first_failure"}
_BOOL_RESULTS = {"safe", "deflection_ok"}


def unpack(scene: str, vec: np.ndarray) -> dict:
    """Kernel output vector -> dict under the names of docs/model.md."""
    rows = SCENE_RESULTS[scene]
    out: dict = {}
    for i, (name, _, _) in enumerate(rows):
        x = float(vec[i])
        if name == "outcome":
            out[name] = OUTCOMES[int(x)]
        elif name == "status":
            out[name] = STATUS_MESSAGES[int(x)]
        elif name in _INT_RESULTS:
            out[name] = int(x)
        elif name in _BOOL_RESULTS:
            out[name] = bool(x) if math.isfinite(x) else False
        else:
            out[name] = x
    return out


def unpack_columns(rows: tuple, out: np.ndarray) -> dict:
    """Kernel output rows (one per run or cycle; `rows`: their layout, e.g. STREAM_CYCLE_RESULTS)
    -> {name: NumPy column}, decoded as `unpack` decodes one (codes to names, NaN counts and flags
    to 0 and False)."""
    cols = {}
    for i, (name, _, _) in enumerate(rows):
        x = out[:, i]
        finite = np.isfinite(x)
        if name == "outcome":
            cols[name] = np.array(OUTCOMES, dtype=object)[x.astype(np.int64)]
        elif name == "status":
            cols[name] = np.array(STATUS_MESSAGES, dtype=object)[x.astype(np.int64)]
        elif name in _INT_RESULTS:
            cols[name] = np.where(finite, x, 0.0).astype(np.int64)
        elif name in _BOOL_RESULTS:
            cols[name] = finite & (x != 0.0)
        else:
            cols[name] = x.copy()
    return cols


def unpack_cycles(out: np.ndarray) -> dict:
    """A stream kernel's rows (STREAM_CYCLE_RESULTS, one per cycle) -> {name: list}."""
    return {name: col.tolist() for name, col in unpack_columns(STREAM_CYCLE_RESULTS, out).items()}


def stream_summary(cycles: dict, period: float) -> dict:
    """The results of a stream (docs/model.md §14, STREAM_RESULTS) from its cycles' ({name: list}):
    the counts, the first failure, the worst values and the throughput 3600 / T (14.5)."""
    outcomes = cycles["outcome"]
    first = next((k for k, o in enumerate(outcomes) if o != "scraped"), -1)

    def worst(name: str) -> float:
        vals = [v for v in cycles[name] if not math.isnan(v)]
        return max(vals) if vals else math.nan

    return {"n_cycles": len(outcomes), "n_scraped": sum(o == "scraped" for o in outcomes), "first_failure": first,
            "worst_overload": worst("overload"), "worst_deflection": worst("deflection_max"),
            "worst_start_amplitude": worst("start_amplitude"), "throughput": 3600.0 / period}


def stream_results(out: np.ndarray, period: float) -> dict:
    """A stream kernel's rows -> the stream's results plus "cycles", a DataFrame with one row per
    cycle (STREAM_CYCLE_RESULTS; units in df.attrs["units"])."""
    import pandas as pd

    cycles = unpack_cycles(out)
    res = stream_summary(cycles, period)
    df = pd.DataFrame(cycles)
    df.index.name = "cycle"
    df.attrs["units"] = {name: unit for name, unit, _ in STREAM_CYCLE_RESULTS}
    res["cycles"] = df
    return res
