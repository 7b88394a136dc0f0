"""REPORT.md section 6: consecutive cycles (scene stream, docs/model.md §14, sweeps/period.yaml): which
streams are safe, the shortest safe period of each element (shortest_safe_period), and what the
table says in sentences built from its numbers.
"""
from __future__ import annotations

import math

import numpy as np

from fencesweep.report.analysis import STREAM_FIGURE_CYCLES


def _element(row) -> str:
    if row["drive"] == "rigid":
        return "rigid fence"
    from fencesweep.model.params import relative_damping

    return f"{row['B2']:g} / {row['K2']:g} (Psi = {relative_damping(row['B2'], row['K2'], row['I2']):.2f})"


def stream_safety(df):
    """Per stream (element, t_c, period) of a stream table: whether every cycle is scraped with
    overload <= 1 and deflection_max <= dalpha_perm, and the stream's worst values."""
    df = df.assign(element=df.apply(_element, axis=1),
                   ok=(df["outcome"] == "scraped") & df["safe"] & df["deflection_ok"])
    return (df.groupby(["element", "t_c", "period"], sort=False)
              .agg(ok=("ok", "all"), worst_overload=("worst_overload", "first"),
                   worst_deflection=("worst_deflection", "first"),
                   worst_start_amplitude=("worst_start_amplitude", "first"), n_scraped=("n_scraped", "first"),
                   n_cycles=("n_cycles", "first"), first_failure=("first_failure", "first"))
              .reset_index())


def shortest_safe_period(g) -> float:
    """The shortest period of one element's streams (sorted by period) from which every longer
    period of the sweep is safe too (NaN if the longest is not)."""
    ok = g["ok"].to_numpy()
    if not ok[-1]:
        return math.nan
    bad = np.nonzero(~ok)[0]
    return float(g["period"].iloc[bad[-1] + 1 if len(bad) else 0])


def _values(df, col: str, default: float, conv=float) -> str:
    """The distinct values of a column, ' / '-joined (the default when an old table lacks the column)."""
    vals = sorted(set(df[col])) if col in df else [default]
    return " / ".join(f"{conv(v):.3g}" for v in vals)


def stream_section(df) -> list[str]:
    """Section 6 of the report: consecutive cycles (scene stream, sweeps/period.yaml)."""
    S = stream_safety(df)
    n = int(S["n_cycles"].iloc[0])
    L = ["## 6. Consecutive cycles: how short may the period be? (scene `stream`, docs/model.md §14)", "",
         f"Table `period.parquet` (`sweeps/period.yaml`): streams of {n} work cycles, small_far and long_near "
         "alternating, each cycle starting with the fence's state that the one before left (nothing is reset), "
         "the drive resting between cycles; the period T from t_c to 2 t_c in steps of "
         f"{np.diff(np.sort(S['period'].unique()))[0]:.2g} s, v = {_values(df, 'v', 2.0)} m/s. A stream is **safe** "
         "when every one of its cycles is scraped with overload <= 1 and deflection_max <= dalpha_perm "
         f"({_values(df, 'dalpha_perm', math.radians(15.0), math.degrees)} deg). The shortest safe "
         "period is the shortest T of the sweep from which every longer T is safe too; its throughput is 3600 / T "
         "packages per hour.", "",
         "| element | t_c [s] | shortest safe period [s] | throughput [1/h] | safe periods in [t_c, 2 t_c] | "
         "at T = t_c: worst overload / largest start amplitude [deg] | at T = 2 t_c: worst overload / largest "
         "start amplitude [deg] | at T = t_c: scraped, first failure |",
         "|---|---|---|---|---|---|---|---|"]
    for (element, tc), g in S.groupby(["element", "t_c"], sort=False):
        g = g[g["period"] <= 2 * tc + 1e-9].sort_values("period")
        first, last = g.iloc[0], g.iloc[-1]
        T = shortest_safe_period(g)
        fail = "none" if first["first_failure"] < 0 else f"cycle {int(first['first_failure'])}"
        L.append(f"| {element} | {tc:g} | {'none' if math.isnan(T) else f'{T:g}'} | "
                 f"{'-' if math.isnan(T) else f'{3600 / T:.0f}'} | {int(g['ok'].sum())} of {len(g)} | "
                 f"{first['worst_overload']:.3f} / {math.degrees(first['worst_start_amplitude']):.2f} | "
                 f"{last['worst_overload']:.3f} / {math.degrees(last['worst_start_amplitude']):.2f} | "
                 f"{int(first['n_scraped'])} of {n}, {fail} |")
    L += ["", *_stream_reading(S, df),
          "", f"Figure [`stream_deflection.png`](figures/stream_deflection.png): the deflection over "
          f"{_stream_figure_cycles()} cycles at T = t_c for the three elements (the rigid fence has none)."]
    return L


def _stream_figure_cycles() -> int:

    return STREAM_FIGURE_CYCLES


def _outcomes(df, element: str, tc: float, period: float) -> str:
    """'10 scraped, 10 escaped': the outcomes of one stream's cycles."""
    rows = df[(df.apply(_element, axis=1) == element) & (df["t_c"] == tc) & np.isclose(df["period"], period)]
    return ", ".join(f"{c} {o}" for o, c in rows["outcome"].value_counts().items())


def _stream_reading(S, df) -> list[str]:
    """What the stream table says, in sentences built from its numbers."""
    out = []
    S = S[S["period"] <= 2 * S["t_c"] + 1e-9]
    flex = S[S["element"] != "rigid fence"]
    at_tc = flex[np.isclose(flex["period"], flex["t_c"])]
    if len(at_tc) and at_tc["ok"].all():
        out.append(f"* Every flexible element is safe at T = t_c, for both t_c: the shortest period is the drive's "
                   f"own cycle, not the element's settling. What one cycle leaves in the element reaches the next "
                   f"start with at most {math.degrees(at_tc['worst_start_amplitude'].max()):.2f} deg of amplitude "
                   f"(the paper's element at t_c = {at_tc.loc[at_tc['worst_start_amplitude'].idxmax(), 't_c']:g} s), "
                   f"and the worst overload of a stream at T = t_c is at most "
                   f"{at_tc['worst_overload'].max():.3f}.")
    for (element, tc), g in S.groupby(["element", "t_c"], sort=False):
        g = g[g["period"] <= 2 * tc + 1e-9]
        if not g["ok"].any():
            lo, hi = g["period"].min(), g["period"].max()
            out.append(f"* The {element} at t_c = {tc:g} s is safe at no period: the first failure is cycle "
                       f"{int(g['first_failure'].min())} at every T; the cycles at T = {lo:g} s: "
                       f"{_outcomes(df, element, tc, lo)}, at T = {hi:g} s: {_outcomes(df, element, tc, hi)}. "
                       f"(The fence has no state to carry; the rigid drive is at rest at every cycle's start.)")
    for element, g in flex.groupby("element", sort=False):
        lo = g[np.isclose(g["period"], g["t_c"])]
        hi = g.sort_values("period").groupby("t_c").tail(1)
        d = (lo.set_index("t_c")["worst_overload"] - hi.set_index("t_c")["worst_overload"]).abs().max()
        out.append(f"* {element}: the worst overload of its streams differs by "
                   f"{'less than 0.001' if d < 5e-4 else f'at most {d:.3f}'} between T = t_c and T = 2 t_c.")
    return out
