"""Sequential sampling of failure probabilities, and their intervals: pure functions, no engine.

Each unit (an element at an operating point) is looked at after n_1 < n_2 < ... < n_K samples, and
at look k its Clopper-Pearson interval of P(any) is formed at level 1 - alpha_k; the unit stops
when the interval lies wholly below p_max ("below") or wholly above it ("above"), else at the cap
("undecided"). The looks and their levels are a plan fixed before any sample is seen (`look_plan`),
with alpha_1 + ... + alpha_K = alpha: by the union bound the K intervals of a unit hold all together
with probability >= 1 - alpha, so the interval at whichever look the unit stops (a look chosen by
the data) still covers the true probability with probability >= 1 - alpha: the interval stays
honest under repeated looks. The plan spends alpha where decisions can be made: a small share at a
first, screening look (a unit far above p_max is decided there even at a small level), then, from
the first size at which a unit without a failure can be decided below, half of what is left at
each look (most units that are not near p_max decide at the first of these looks, which therefore
gets the largest level). Clopper-Pearson because it is exact for a binomial count (conservative,
never below its level, also at 0 failures, where the Wald interval collapses to a point); it is
honest only for independent draws from the population, which is why the samples are plain
pseudo-random (a low-discrepancy sequence is not a binomial sample: its count has no binomial law,
and a binomial interval around it means nothing stated).

`run_rounds` drives the rounds with any `evaluate(units, start, stop)` that returns the events of
samples [start, stop) of each unit: the engine (risk/run.py) or a Bernoulli stand-in (tests).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from fencesweep.study.spec.risk import SCREEN, look_plan, zero_break_size  # noqa: F401 (the plan's home)

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
    alpha: np.ndarray  # [units]: the level spent at the unit's last look (its interval's)
    rounds: list = field(default_factory=list)  # per round: (n_k, units sampled, cycles)

    @property
    def cycles(self) -> int:
        return int(self.n.sum())


def run_rounds(n_units: int, evaluate: Callable, plan: tuple, p_max: float, sequential: bool = True) -> State:
    """Sample every unit round by round on `plan` = (sizes, alphas) (look_plan) and decide it.

    evaluate(units, start, stop) -> bool array [len(units), stop - start, len(EVENTS)]: whether
    sample i of unit u broke each constraint. With sequential False every unit runs to the last
    size of the plan and is decided there alone, at the plan's whole alpha (a fixed sample: one look)."""
    sizes, alphas = plan
    if not sequential:
        sizes, alphas = sizes[-1:], [sum(alphas)]
    st = State(np.zeros((n_units, len(ALL)), np.int64), np.zeros(n_units, np.int64),
               np.full(n_units, "", dtype=object), np.zeros(n_units, np.int64), np.full(n_units, alphas[0]))
    start = 0
    for j, (stop, alpha_look) in enumerate(zip(sizes, alphas)):
        units = np.flatnonzero(st.decision == "")
        if not len(units):
            break
        ev = np.asarray(evaluate(units, start, stop), dtype=bool)
        counts = np.concatenate([ev.sum(axis=1), ev.any(axis=2).sum(axis=1)[:, None]], axis=1)
        st.counts[units] += counts
        st.n[units] = stop
        st.looks[units] += 1
        st.alpha[units] = alpha_look
        st.rounds.append((stop, len(units), len(units) * (stop - start)))
        d = decide(st.counts[units, -1], stop, p_max, alpha_look)
        if j == len(sizes) - 1:
            d = np.where(d == "", UNDECIDED, d)
        st.decision[units] = d
        start = stop
    return st


def intervals(state: State) -> dict:
    """{event: (p, lo, hi)} per unit: the share and its Clopper-Pearson interval at the level of the
    unit's last look, 1 - state.alpha."""
    out = {}
    for j, name in enumerate(ALL):
        k = state.counts[:, j]
        lo, hi = clopper_pearson(k, state.n, state.alpha)
        out[name] = (np.where(state.n > 0, k / np.maximum(state.n, 1), np.nan), lo, hi)
    return out


def one_look_decisions(cum: np.ndarray, p_max: float, alpha: float) -> np.ndarray:
    """[units, n]: the decision a fixed sample of n = 1, 2, ... would reach at one look at level
    1 - alpha, from cum[u, n - 1], the count of P(any) events in unit u's first n samples."""
    n = np.arange(1, cum.shape[1] + 1)[None, :]
    return decide(cum, n, p_max, alpha)


def fixed_size_for(decision: np.ndarray, cum: np.ndarray, p_max: float, alpha: float) -> tuple:
    """(n, asked): the smallest n at which a fixed sample of n per unit (one look at 1 - alpha) reaches
    `decision` on every unit `asked`: those decided (not UNDECIDED) whose decision the fixed sample of
    all cum's samples reaches too (two rules that each err with probability <= alpha may differ on a
    unit near p_max). n is None when no n does; known only in hindsight, so the fixed sample at its best."""
    reach = one_look_decisions(cum, p_max, alpha) == decision.astype(str)[:, None]
    asked = (decision != UNDECIDED) & reach[:, -1]
    every = reach[asked].all(axis=0)
    return (int(np.argmax(every)) + 1 if every.any() else None), asked


def least_sizes(decision: np.ndarray, cum: np.ndarray, p_max: float, alpha: float) -> np.ndarray:
    """Per unit the least n at which one look at level 1 - alpha reaches its `decision` on its first n
    samples (0 where none does): what a rule that knew where to stop would spend. A rule that stops at
    n with an interval at level >= 1 - alpha excluding p_max spends at least this on these samples
    (Clopper-Pearson intervals widen as the level rises), so the sum bounds every honest rule's cycles."""
    reach = one_look_decisions(cum, p_max, alpha) == decision.astype(str)[:, None]
    return np.where(reach.any(axis=1), np.argmax(reach, axis=1) + 1, 0)
