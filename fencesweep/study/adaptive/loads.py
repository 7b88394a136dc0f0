"""Adaptive maps, per element: in which order its loads run and when it stops.

One load proves an element infeasible: its cycle breaks a constraint (its own margin, the
smallest of 1 - value / limit over the constraints and -1 for a load not scraped, is negative:
exactly when the element's min_margin over all its loads would be, envelope.finish). So the
loads run in the order most likely to break one, and the element stops at the first that does.

* Order. The element's reference elements (the simulated corners of the cell it lies in,
  adaptive.Refiner) have per-load margins (measured, or predicted when they skipped the load;
  NaN when a reference stopped before it). From the values known, a load's order key is the
  smallest reference margin minus `kappa` x their spread (clipped to [-1, 1]; 0, "unknown",
  where no reference has a value): a load that broke a constraint at a reference runs first.
  Loads run by that key, then by their smallest reference margin, then by how often they broke
  a constraint in the elements simulated so far, then by index (the coarse pass, which has no
  references, runs the loads by how often they broke one, then by index). A load's prediction,
  for the stop, is the same but -inf where any reference lacks a value (nothing is predicted
  from a neighbour that did not run the load).
* Stop. After each load: stop if it broke a constraint (infeasible); stop if the smallest
  prediction of the loads left is at least `theta` and at least the element's smallest
  margin so far plus `delta` (feasible: the loads left are predicted to break nothing, and to
  leave its min_margin and binding constraint as they are). Otherwise run the next load.

A feasible element with predicted loads is a verdict by rule, not by every load: benchmarks/
adaptive/refine.py counts, against the full grid, the skipped loads that would have broken a
constraint (none on its studies) and the elements whose min_margin differs.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from fencesweep.study.spec import design as DS


@dataclass(frozen=True)
class LoadRule:
    """When an element stops with loads left (module docstring); predict False runs every load
    of a feasible element."""

    theta: float = 0.05
    delta: float = 0.02
    kappa: float = 1.0
    predict: bool = True

    def as_dict(self) -> dict:
        return {"theta": self.theta, "delta": self.delta, "kappa": self.kappa, "predict": self.predict}


def load_margin(res: dict, dlim: float, limits: DS.Limits) -> float:
    """One cycle's margin to the constraints (envelope.finish on one load): the smallest of
    1 - value / limit, and -1 when the load is not scraped; NaN values are passed over, as the
    per-design-point table passes them over."""
    out = math.inf
    if limits.scraped and res["outcome"] != "scraped":
        out = -1.0
    ov = res["overload"]
    ov = 0.0 if ov is None or ov != ov else ov  # no contact: no force
    out = min(out, 1.0 - ov / limits.overload)
    for value, lim in ((res["deflection_max"], dlim), (res["residual_amplitude"], limits.residual_amplitude)):
        if lim is not None and value is not None and value == value:
            out = min(out, 1.0 - value / lim)
    return out


def predictions(ref_values: np.ndarray, kappa: float) -> tuple:
    """(prediction, smallest reference margin, order key) per load from the references' values
    [R, L] (NaN: no value), module docstring."""
    n = ref_values.shape[1]
    if ref_values.shape[0] == 0:
        return np.full(n, -np.inf), np.full(n, np.inf), np.zeros(n)
    v = np.clip(ref_values, -1.0, 1.0)
    missing = np.isnan(v).any(axis=0)
    known = ~np.isnan(v).all(axis=0)
    low = np.where(np.isnan(v), np.inf, v).min(axis=0)
    high = np.where(np.isnan(v), -np.inf, v).max(axis=0)
    key = np.where(known, low - kappa * (high - low), 0.0)
    pred = np.where(missing, -np.inf, key)
    return pred, low, key


def order(key: np.ndarray, low: np.ndarray, broke: np.ndarray) -> np.ndarray:
    """The loads in the order they run (module docstring); broke: per load, the elements whose
    cycle broke a constraint so far."""
    n = len(key)
    return np.lexsort((np.arange(n), -broke, low, key))


def following(pred: np.ndarray) -> np.ndarray:
    """Per position of loads in running order (their predictions `pred`), the smallest
    prediction of the loads after it (inf after the last): what stop() compares."""
    out = np.full(len(pred), np.inf)
    if len(pred) > 1:
        out[:-1] = np.minimum.accumulate(pred[::-1])[::-1][1:]
    return out


def stop(margin: float, smallest: float, left: float, rule: LoadRule) -> str | None:
    """After a load with `margin` (the element's smallest so far `smallest`; `left` the smallest
    prediction of the loads left): 'broken', 'predicted' (the loads left are predicted safe) or
    None (run the next)."""
    if margin < 0.0:
        return "broken"
    if rule.predict and left >= max(rule.theta, smallest + rule.delta):
        return "predicted"
    return None
