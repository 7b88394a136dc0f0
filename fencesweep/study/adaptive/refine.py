"""Adaptive maps: which elements of a design grid to simulate, and what the others are.

A map is a grid of design points (elements) over d ordered axes; each element has a verdict
(feasible or not), the constraint that binds and the signed margin to each constraint
(spec/envelope.py: 1 - worst / limit). Most of a map is far from any boundary. The Refiner decides,
level by level, which elements must be simulated and infers the others. Pure: arrays in, arrays
out; no engine, no files (adaptive/run.py runs the elements).

* Levels. Level h is the lattice of grid indices that are multiples of h on every axis, plus
  each axis's last index (`lattice`). The coarse level is the largest power of two that leaves
  at least COARSE_INTERVALS intervals on the longest axis (8 on an 81-point axis); its lattice
  is simulated (the coarse pass). A cell of level h is a box between neighbouring lattice
  coordinates; its 2^d corners are known (simulated or inferred).
* Agreement. Elements agree (`agree`) when they have the same verdict, the feasible ones the
  same binding constraint, and their smallest margins m (clipped to [-1, 1]) keep
  |m| >= kappa x (max m - min m) + band: the margin would have to bend more between them than
  they show, or come within `band` of a limit, for the verdict to change between them.
* A cell whose corners agree is settled: its inside is inferred. Any other cell is halved on
  every axis (level h / 2). Each new lattice point lies on a face of its cell (the box spanned
  by the axes on which it is halfway); if the face's corners agree (and, with `halo`, none of
  them is a corner of a cell whose corners disagree in verdict), the point is inferred from
  them, else it is simulated. Cells one index wide have no inside: refinement stops there.
* Inference. An inferred element takes its face's or cell's common verdict and binding, and its
  margins are the multilinear interpolation of the corners' (in index space; margin_scraped,
  +inf where every load was scraped, is the smallest finite corner value where the corners
  differ). A finer cell overrides a coarser one.

A simulated element's verdict is the full grid's (the same cycles). An inferred one can be wrong
only where the verdict changes between elements that agree, i.e. where the margins bend more
between the corners than the corners show: this is an assumption on the map's smoothness at the
scale of the cells, not a proof. results/adaptive.md measured it against the full grid.
"""
from __future__ import annotations

import itertools
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

COARSE_INTERVALS = 8  # intervals of the coarse level on the longest axis, at least
CLIP = 1.0  # margins are clipped to [-CLIP, CLIP] in the agreement test (-58 is "broken", as -1 is)
UNKNOWN, SAMPLED, INFERRED = 0, 1, 2  # an element's status


@dataclass(frozen=True)
class Rule:
    """When elements agree (module docstring)."""

    kappa: float = 1.0
    band: float = 0.02
    halo: bool = True
    binding: bool = True

    def as_dict(self) -> dict:
        return {"kappa": self.kappa, "band": self.band, "halo": self.halo, "binding": self.binding}


class Cells(NamedTuple):
    """Boxes of a level: their map, lowest and highest corner index per axis ([N], [N, d], [N, d])."""

    map: np.ndarray
    lo: np.ndarray
    hi: np.ndarray

    def __len__(self) -> int:
        return len(self.map)

    def take(self, sel) -> "Cells":
        return Cells(self.map[sel], self.lo[sel], self.hi[sel])


@dataclass(frozen=True)
class Grid:
    """n_maps maps of `shape` elements each; element id = map x size + the index raveled (C order)."""

    n_maps: int
    shape: tuple

    @property
    def size(self) -> int:
        return int(np.prod(self.shape))

    @property
    def n_elements(self) -> int:
        return self.n_maps * self.size

    def ids(self, maps: np.ndarray, idx: np.ndarray) -> np.ndarray:
        """Element ids of maps [N] at indices idx [N, d]."""
        idx = np.asarray(idx, dtype=np.int64).reshape(-1, len(self.shape))
        flat = np.ravel_multi_index(tuple(idx.T), self.shape)
        return np.asarray(maps, dtype=np.int64) * self.size + flat

    def index(self, ids: np.ndarray) -> tuple:
        """(maps [N], indices [N, d]) of element ids."""
        maps, flat = np.divmod(np.asarray(ids, dtype=np.int64), self.size)
        return maps, np.stack(np.unravel_index(flat, self.shape), axis=1)


def lattice(n: int, h: int) -> np.ndarray:
    """The coordinates of level h on an axis of n points: the multiples of h and n - 1."""
    return np.unique(np.r_[np.arange(0, n, h), n - 1]).astype(np.int64)


def coarse_step(shape: tuple, intervals: int = COARSE_INTERVALS) -> int:
    """The coarse level: the largest power of two h with (longest axis - 1) / h >= intervals (at least 1)."""
    longest, h = max(shape) - 1, 1
    while longest / (2 * h) >= intervals:
        h *= 2
    return h


def patterns(d: int) -> np.ndarray:
    """The 2^d corner patterns of a box: bit j set = the high end on axis j."""
    return np.array(list(itertools.product((0, 1), repeat=d)), dtype=bool).reshape(2 ** d, d)


def corners(grid: Grid, cells: Cells) -> np.ndarray:
    """Element ids of each cell's 2^d corners [N, 2^d], in the order of patterns(d)."""
    pats = patterns(len(grid.shape))
    out = np.empty((len(cells), len(pats)), dtype=np.int64)
    for k, p in enumerate(pats):
        out[:, k] = grid.ids(cells.map, np.where(p, cells.hi, cells.lo))
    return out


def weights(t: np.ndarray) -> np.ndarray:
    """Multilinear weights [P, 2^d] of points at fractions t [P, d] of a box (patterns' order)."""
    pats = patterns(t.shape[1])
    return np.stack([np.prod(np.where(p, t, 1.0 - t), axis=1) for p in pats], axis=1)


def interpolate(values: np.ndarray, w: np.ndarray) -> np.ndarray:
    """Interpolate corner values [P, 2^d] with weights [P, 2^d]; a row with an infinite value
    (margin_scraped) gives its smallest finite value, or inf if none is finite."""
    finite = np.isfinite(values)
    out = (w * np.where(finite, values, 0.0)).sum(axis=1)
    mixed = ~finite.all(axis=1)
    if mixed.any():
        smallest = np.where(finite, values, np.inf).min(axis=1)
        out[mixed] = smallest[mixed]
    return out


def agree(feasible: np.ndarray, binding: np.ndarray, margin: np.ndarray, rule: Rule) -> tuple:
    """Per row of corner values [N, k]: (the corners agree (module docstring), they agree in verdict)."""
    same = feasible.all(axis=1) | (~feasible).all(axis=1)
    ok = same & (~feasible.all(axis=1) | (binding == binding[:, :1]).all(axis=1) | (not rule.binding))
    m = np.clip(margin, -CLIP, CLIP)
    ok &= np.abs(m).min(axis=1) >= rule.kappa * (m.max(axis=1) - m.min(axis=1)) + rule.band
    return ok, same


class Refiner:
    """The refinement of module docstring on `grid`, driven by ask() / tell(): deterministic in
    the values told. ask() returns the elements to simulate next (the coarse lattice first) and
    their reference elements (the simulated corners of the cell each lies in: the loads that
    were worst there are tried first); tell() gives their verdicts; ask() returning no element
    means every element is settled, and result() fills in the others."""

    def __init__(self, grid: Grid, rule: Rule = Rule(), n_margins: int = 4, coarse: int | None = None):
        self.grid, self.rule = grid, rule
        self.h = coarse or coarse_step(grid.shape)
        n = grid.n_elements
        self.status = np.zeros(n, dtype=np.int8)
        self.feasible = np.zeros(n, dtype=bool)
        self.binding = np.zeros(n, dtype=np.int64)
        self.margins = np.full((n, n_margins), np.nan)
        self.min_margin = np.full(n, np.nan)
        self.cells: Cells | None = None  # the open cells of level h
        self.settled: list = []  # settled cells, coarse to fine
        self.levels: list = []  # per level: (h, simulated, inferred)

    def tell(self, ids: np.ndarray, feasible: np.ndarray, binding: np.ndarray, margins: np.ndarray) -> None:
        ids = np.asarray(ids, dtype=np.int64)
        self.status[ids] = SAMPLED
        self.feasible[ids], self.binding[ids], self.margins[ids] = feasible, binding, margins
        self.min_margin[ids] = np.asarray(margins, dtype=float).min(axis=1)

    def ask(self) -> tuple:
        """(element ids to simulate, their reference elements [N, 2^d], -1 padded); empty: done."""
        if self.cells is None:  # the coarse pass
            self.cells = self._first_cells()
            ids = np.unique(corners(self.grid, self.cells))
            self.levels.append((self.h, len(ids), 0))
            return ids, np.full((len(ids), 1), -1, dtype=np.int64)
        if (self.status[np.unique(corners(self.grid, self.cells))] == UNKNOWN).any():
            raise RuntimeError("ask() before every element asked for was told")
        while len(self.cells):
            ids, refs = self._refine()
            if len(ids):
                return ids, refs
        return np.empty(0, dtype=np.int64), np.empty((0, 1), dtype=np.int64)

    def _first_cells(self) -> Cells:
        per_axis = [lattice(n, self.h) for n in self.grid.shape]
        spans = list(itertools.product(*[list(zip(c[:-1], c[1:])) for c in per_axis]))
        d = len(self.grid.shape)
        lo = np.array([[a for a, _ in s] for s in spans], dtype=np.int64).reshape(len(spans), d)
        hi = np.array([[b for _, b in s] for s in spans], dtype=np.int64).reshape(len(spans), d)
        maps = np.repeat(np.arange(self.grid.n_maps, dtype=np.int64), len(spans))
        return Cells(maps, np.tile(lo, (self.grid.n_maps, 1)), np.tile(hi, (self.grid.n_maps, 1)))

    def _values(self, ids: np.ndarray) -> tuple:
        return self.feasible[ids], self.binding[ids], self.min_margin[ids]

    def _refine(self) -> tuple:
        """Settle the open cells whose corners agree, halve the others; infer the new points
        whose face agrees, return the rest to simulate."""
        cells, h = self.cells, self.h
        c = corners(self.grid, cells)
        ok, same = agree(*self._values(c), self.rule)
        hollow = ((cells.hi - cells.lo) <= 1).all(axis=1)
        self.settled.append(cells.take(ok & ~hollow))
        hot = np.unique(c[~same]) if self.rule.halo else np.empty(0, dtype=np.int64)
        todo = cells.take(~ok & ~hollow)
        self.cells, self.h = split(todo, h), max(h // 2, 1)
        if not len(todo):
            return np.empty(0, dtype=np.int64), np.empty((0, 1), dtype=np.int64)
        ids, face_lo, face_hi, parent = self._new_points(todo, h)
        fc = corners(self.grid, Cells(todo.map[parent], face_lo, face_hi))
        fine, _ = agree(*self._values(fc), self.rule)
        fine &= ~np.isin(fc, hot).any(axis=1)
        self._infer_points(ids[fine], fc[fine], face_lo[fine], face_hi[fine])
        sample = ~fine
        self.levels.append((self.h, int(sample.sum()), int(fine.sum())))
        refs = c[~ok & ~hollow][parent[sample]]
        return ids[sample], np.where(self.status[refs] == SAMPLED, refs, -1)

    def _new_points(self, todo: Cells, h: int) -> tuple:
        """The lattice points of level h / 2 in the cells `todo` that are not known yet, each
        once (the first cell that holds it): ids, their face's lowest and highest corner, and
        the index of that cell in `todo`."""
        half = h // 2
        d = todo.lo.shape[1]
        ids, los, his, parents = [], [], [], []
        for p in patterns(d)[1:]:  # which axes are halfway (not all at a corner)
            mid = todo.lo + half
            valid = (~p | (mid < todo.hi)).all(axis=1)
            idx = np.where(p, mid, todo.lo)[valid]
            for q in patterns(d):  # each corner choice on the other axes gives another point
                if (q & p).any():
                    continue
                at = np.where(q, todo.hi[valid], idx)
                at = np.where(p, idx, at)
                ids.append(self.grid.ids(todo.map[valid], at))
                los.append(np.where(p, todo.lo[valid], at))
                his.append(np.where(p, todo.hi[valid], at))
                parents.append(np.nonzero(valid)[0])
        ids = np.concatenate(ids)
        _, first = np.unique(ids, return_index=True)
        first = first[self.status[ids[first]] == UNKNOWN]
        first.sort()
        return ids[first], np.concatenate(los)[first], np.concatenate(his)[first], np.concatenate(parents)[first]

    def _infer_points(self, ids: np.ndarray, fc: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> None:
        """Infer elements ids from their faces (corner ids fc, boxes lo..hi)."""
        if not len(ids):
            return
        _, idx = self.grid.index(ids)
        w = weights((idx - lo) / np.where(hi > lo, hi - lo, 1))
        self.status[ids] = INFERRED
        self._fill(ids, fc, w, self.feasible, self.binding, self.margins, self.min_margin)

    def _fill(self, ids: np.ndarray, fc: np.ndarray, w: np.ndarray, feas, bind, marg, mm) -> None:
        """Elements ids from corners fc [N, 2^d] at weights w [N, 2^d] (module docstring): the
        corners' verdict, their binding constraint when they share it (else the smallest of the
        interpolated margins), the margins and min_margin interpolated, from this refiner's values."""
        feas[ids] = self.feasible[fc[:, 0]]
        for j in range(marg.shape[1]):
            marg[ids, j] = interpolate(self.margins[fc, j], w)
        b = self.binding[fc]
        bind[ids] = np.where((b == b[:, :1]).all(axis=1), b[:, 0], marg[ids].argmin(axis=1))
        mm[ids] = interpolate(self.min_margin[fc], w)

    def result(self) -> tuple:
        """(status, feasible, binding, margins, min_margin) of every element: the settled cells'
        insides inferred from their corners, coarse to fine (a finer cell overrides a coarser one)."""
        status, feas, bind = self.status.copy(), self.feasible.copy(), self.binding.copy()
        marg, mm = self.margins.copy(), self.min_margin.copy()
        for cells in self.settled:
            cs = corners(self.grid, cells)
            for k in range(len(cells)):
                axes = [np.arange(a, b + 1) for a, b in zip(cells.lo[k], cells.hi[k])]
                idx = np.array(list(itertools.product(*axes)), dtype=np.int64)
                ids = self.grid.ids(np.full(len(idx), cells.map[k]), idx)
                free = self.status[ids] != SAMPLED
                if not free.any():
                    continue
                w = weights((idx[free] - cells.lo[k]) / (cells.hi[k] - cells.lo[k]))
                status[ids[free]] = INFERRED
                self._fill(ids[free], np.broadcast_to(cs[k], w.shape), w, feas, bind, marg, mm)
        return status, feas, bind, marg, mm


def split(cells: Cells, h: int) -> Cells:
    """The halves of level h // 2 of cells of level h (an axis shorter than h / 2 + 1 stays whole)."""
    mid = cells.lo + h // 2
    cut = mid < cells.hi
    parts = []
    for p in patterns(cells.lo.shape[1]):
        keep = (cut | ~p).all(axis=1)  # a high half exists only where the axis is cut
        lo = np.where(p & cut, mid, cells.lo)
        hi = np.where(~p & cut, mid, cells.hi)
        parts.append(Cells(cells.map[keep], lo[keep], hi[keep]))
    return Cells(*(np.concatenate(x) for x in zip(*parts)))
