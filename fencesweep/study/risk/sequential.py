"""Sequential sampling of failure probabilities, and their intervals: pure functions, no engine.

Each unit (an element at an operating point) is looked at after n_1 < n_2 < ... < n_K samples, a
geometric schedule fixed before any sample is seen (first, first x growth, ..., cap). At each look
the Clopper-Pearson interval of P(any) at level 1 - alpha / K is formed; the unit stops when the
interval lies wholly below p_max ("below") or wholly above it ("above"), else at the cap
("undecided"). By the union bound over the K looks, the K intervals of a unit hold all together
with probability >= 1 - alpha, so the interval at whichever look the unit stops (a look chosen by
the data) still covers the true probability with probability >= 1 - alpha: the interval stays
honest under repeated looks. Clopper-Pearson because it is exact for a binomial count
(conservative, never below its level, also at 0 failures, where the Wald interval collapses to a
point); it is honest only for independent draws from the population, which is why the samples
are plain pseudo-random (a low-discrepancy sequence is not a binomial sample: its count has no
binomial law, and a binomial interval around it means nothing stated).

`run_rounds` drives the rounds with any `evaluate(units, start, stop)` that returns the events of
samples [start, stop) of each unit: the engine (risk/run.py) or a Bernoulli stand-in (tests).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable

import numpy as np

#: the events counted per sample, in this order; "any" is their union
EVENTS = ("overload", "not_scraped", "deflection", "residual")
ALL = (*EVENTS, "any")
BELOW, ABOVE, UNDECIDED = "below", "above", "undecided"


def clopper_pearson(k, n, alpha: float) -> tuple:
    """The two-sided Clopper-Pearson interval (lo, hi) of a binomial proportion, k of n, at level
    1 - alpha (arrays broadcast; n = 0 gives (0, 1))."""
    from scipy.stats import beta

    k, n = np.asarray(k, dtype=float), np.asarray(n, dtype=float)
    with np.errstate(invalid="ignore", divide="ignore"):
        lo = np.where(k > 0, beta.ppf(alpha / 2, k, n - k + 1), 0.0)
        hi = np.where(k < n, beta.ppf(1 - alpha / 2, k + 1, n - k), 1.0)
    return np.nan_to_num(lo, nan=0.0), np.nan_to_num(hi, nan=1.0)


def geometric_schedule(first: int, growth: int, cap: int) -> list:
    """first, first x growth, ... below cap, then cap."""
    out, n = [], first
    while n < cap:
        out.append(n)
        n *= growth
    return out + [cap]


def decide(k_any, n, p_max: float, alpha_look: float) -> np.ndarray:
    """BELOW / ABOVE / "" (not yet) per unit from its count of P(any) events k_any of n."""
    lo, hi = clopper_pearson(k_any, n, alpha_look)
    return np.where(hi < p_max, BELOW, np.where(lo > p_max, ABOVE, ""))


@dataclass
class State:
    """The sampling state of every unit: counts of each event (ALL order), samples, decision, and
    the cycles spent per round."""

    counts: np.ndarray  # [units, 5]
    n: np.ndarray  # [units]
    decision: np.ndarray  # [units]: BELOW / ABOVE / UNDECIDED / "" while sampling
    looks: np.ndarray  # [units]: looks taken
    rounds: list = field(default_factory=list)  # per round: (n_k, units sampled, cycles)

    @property
    def cycles(self) -> int:
        return int(self.n.sum())


def run_rounds(n_units: int, evaluate: Callable, schedule: list, p_max: float, alpha: float,
               sequential: bool = True) -> State:
    """Sample every unit round by round on `schedule` (module docstring) and decide it.

    evaluate(units, start, stop) -> bool array [len(units), stop - start, len(EVENTS)]: whether
    sample i of unit u broke each constraint. With sequential False every unit runs to the last
    entry of the schedule and is decided there alone (a fixed sample: one look at level 1 - alpha)."""
    if not sequential:
        schedule = schedule[-1:]
    alpha_look = alpha / len(schedule)
    st = State(np.zeros((n_units, len(ALL)), np.int64), np.zeros(n_units, np.int64),
               np.full(n_units, "", dtype=object), np.zeros(n_units, np.int64))
    start = 0
    for j, stop in enumerate(schedule):
        units = np.flatnonzero(st.decision == "")
        if not len(units):
            break
        ev = np.asarray(evaluate(units, start, stop), dtype=bool)
        counts = np.concatenate([ev.sum(axis=1), ev.any(axis=2).sum(axis=1)[:, None]], axis=1)
        st.counts[units] += counts
        st.n[units] = stop
        st.looks[units] += 1
        st.rounds.append((stop, len(units), len(units) * (stop - start)))
        d = decide(st.counts[units, -1], stop, p_max, alpha_look)
        if j == len(schedule) - 1:
            d = np.where(d == "", UNDECIDED, d)
        st.decision[units] = d
        start = stop
    return st


def intervals(state: State, alpha_look: float) -> dict:
    """{event: (p, lo, hi)} per unit: the share and its Clopper-Pearson interval at 1 - alpha_look."""
    out = {}
    for j, name in enumerate(ALL):
        k = state.counts[:, j]
        lo, hi = clopper_pearson(k, state.n, alpha_look)
        out[name] = (np.where(state.n > 0, k / np.maximum(state.n, 1), np.nan), lo, hi)
    return out


def fixed_size_for(state: State, ks: Callable[[int], np.ndarray], sizes: list, p_max: float, alpha: float) -> int | None:
    """The smallest n of `sizes` at which a fixed sample (one look, Clopper-Pearson at 1 - alpha)
    reaches the sequential decision of every unit the sequential rule decided (those it left
    undecided at the cap are not asked of it); ks(n) gives the count of P(any) events of each
    unit's first n samples. None: no n of `sizes` does."""
    decided = state.decision != UNDECIDED
    for n in sizes:
        if (decide(ks(n), n, p_max, alpha)[decided] == state.decision[decided]).all():
            return n
    return None
