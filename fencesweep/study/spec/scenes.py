"""A spec's scenes as whole columns: resolved once per combination of the values that params.resolve
reads together, the rest laid out by index (sweep/plan.py plans with it, sweep/assemble.py writes
the table's parameter columns with it).

params.resolve checks most parameters one by one and copies them (params.ALONE); only a few enter
a derived value or a combination check (the load's start, docs/model.md §1; I2 and t_max, §3 and
§12; Psi -> K2, §3). A spec's dimensions (its cases, then its axes, spec.Spec.decode) therefore
split in two: the *free* axes, whose parameters are all in ALONE, and the *core* dimensions, the
rest. resolve runs once per combination of core values present (a *slot*: the envelope study has
64, for its 64 loads, not 419,904 scenes), and a scene's column is its slot's value, or its free
axis's value at its index. The same split numbers each scene's model run (params.model_key): the
slot's key without the free axes' values, and the index of each free axis's value that the key
uses (run_codes). Nothing here loops over scenes in Python.
"""
from __future__ import annotations

import io
import math
import pickle

import numpy as np
import pyarrow as pa

from fencesweep.model import params as P
from fencesweep.study.spec import spec as S
from fencesweep.study.store import table as store
from fencesweep.study.store.columns import arrow_array

#: a dense table of the core combinations is used up to this size (else np.unique sorts them)
_DENSE_SLOTS = 1 << 20


def key_bytes(key: tuple) -> bytes:
    """A model key's pickle, made without a memo: equal keys give the same bytes, whether or not
    their strings are the same objects (binary floats: 0.0 and -0.0 differ, as in a pickle)."""
    buf = io.BytesIO()
    pickler = pickle.Pickler(buf, protocol=5)
    pickler.fast = True
    pickler.dump(key)
    return buf.getvalue()


def alone_names(spec: S.Spec) -> frozenset:
    """The parameters of `spec` that resolve only checks and copies (params.ALONE, module docstring)."""
    if spec.scene == "stream" or spec.loads is not None:
        return frozenset()
    sets_psi = ("Psi" in spec.params or any("Psi" in c["params"] for c in spec.cases)
                or any("Psi" in a.names for a in spec.axes))
    return P.ALONE - {"B2", "K2"} if sets_psi else P.ALONE


def relative_damping(B2, K2, I2):
    """Psi = B2 / (2 sqrt(K2 I2)), NaN where K2 I2 = 0 (docs/model.md §3), on whole columns: the
    same operations as spec.psi_of, so the same bits."""
    k = np.asarray(K2, dtype=np.float64) * I2
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(k > 0, B2 / (2.0 * np.sqrt(np.where(k > 0, k, 1.0))), math.nan)


def _factor(slot: np.ndarray) -> tuple:
    """(the slots present, each scene's position among them), as np.unique(return_inverse)
    gives them, by counting instead of sorting."""
    present = np.flatnonzero(np.bincount(slot)) if len(slot) else np.empty(0, np.int64)
    lut = np.zeros(present[-1] + 1 if len(present) else 0, dtype=np.int64)
    lut[present] = np.arange(len(present))
    return present, lut[slot]


class Scenes:
    """The scenes of `spec` as columns (module docstring). Slots are resolved as calls meet them
    and kept: forget() drops them (a sweep in pieces does, piece after piece)."""

    def __init__(self, spec: S.Spec):
        self.spec = spec
        self.shape = (len(spec.cases),) + tuple(len(a) for a in spec.axes)
        alone = alone_names(spec)
        self.free = tuple(d for d, a in enumerate(spec.axes, 1) if set(a.names) <= alone)
        self.core = tuple(d for d in range(len(self.shape)) if d not in self.free)
        self.core_shape = tuple(self.shape[d] for d in self.core)
        #: free parameter -> (its dimension, its values along it)
        self.free_values = {n: (d, np.array([v[k] for v in spec.axes[d - 1].values], dtype=np.float64))
                            for d in self.free for k, n in enumerate(spec.axes[d - 1].names)}
        self._free_size = math.prod(self.shape[d] for d in self.free)
        self._axis_ids: dict = {}
        self._key_ids: dict = {}
        self._variants: dict = {}
        self.forget()

    def forget(self) -> None:
        """Drop the slots resolved so far (the run numbers of run_codes start again)."""
        self._slot: dict = {}  # core combination (flat index) -> slot
        self.vals: list = []  # resolved set of each slot (None: invalid)
        self.errors: list = []  # why each slot is invalid (None: valid)
        self._slot_key: list = []  # the number of each slot's key without its free values
        self._slot_used: list = []  # the set of free parameters each slot's key uses (_variant)
        self._key_ids.clear()

    # ---- scenes -> slots -----------------------------------------------------------------
    def decode(self, scenes: np.ndarray) -> tuple:
        """Scene numbers -> their index along each dimension (spec.Spec.decode, on arrays)."""
        return np.unravel_index(np.asarray(scenes, dtype=np.int64), self.shape)

    def slots(self, idx: tuple) -> np.ndarray:
        """The slot of each scene of `idx` (decode), resolving the slots not met before."""
        core = [idx[d] for d in self.core]
        flat = np.ravel_multi_index(core, self.core_shape) if len(core) > 1 else np.asarray(core[0], np.int64)
        size = math.prod(self.core_shape)
        if size <= max(len(flat), _DENSE_SLOTS):
            present = np.flatnonzero(np.bincount(flat, minlength=size))
            lut = np.full(size, -1, dtype=np.int64)
            lut[present] = [self._slot_of(int(u)) for u in present]
            return lut[flat]
        present, inverse = np.unique(flat, return_inverse=True)
        return np.array([self._slot_of(int(u)) for u in present], dtype=np.int64)[inverse.ravel()]

    def _slot_of(self, flat: int) -> int:
        """The slot of core combination `flat`, resolved (its free axes at their first value) if new."""
        slot = self._slot.get(flat)
        if slot is not None:
            return slot
        where = dict(zip(self.core, np.unravel_index(flat, self.core_shape)))
        scene = int(np.ravel_multi_index([int(where.get(d, 0)) for d in range(len(self.shape))], self.shape))
        try:
            vals, error = self.spec.resolve(scene), None
        except P.ParameterError as exc:
            vals, error = None, str(exc)
        self._slot[flat] = slot = len(self.vals)
        self.vals.append(vals)
        self.errors.append(error)
        key, used = (-1, ()) if vals is None else self._key_id(vals)
        self._slot_key.append(key)
        self._slot_used.append(self._variant(used))
        return slot

    def _key_id(self, vals: dict) -> tuple:
        """(the number of a slot's model key without its free parameters' values, the free
        parameters the key uses) (module docstring); keys compare as their pickles do."""
        key = P.model_key(vals)
        used = tuple(e[0] for e in key[1:] if e[0] in self.free_values)
        core = (key[0], tuple(e for e in key[1:] if e[0] not in self.free_values), used)
        return self._key_ids.setdefault(key_bytes(core), len(self._key_ids)), used

    def _variant(self, used: tuple) -> int:
        """The number of a set of free parameters that a key uses."""
        return self._variants.setdefault(used, len(self._variants))

    def valid(self, slot: np.ndarray) -> np.ndarray:
        """Whether each slot resolved (an invalid start, ... does not: errors says why)."""
        return np.array([v is not None for v in self.vals], dtype=bool)[slot]

    # ---- columns -------------------------------------------------------------------------
    def columns(self, scenes: np.ndarray) -> dict:
        """The table's label, parameter and derived columns (store.param_columns) of valid
        `scenes`, as Arrow arrays."""
        idx = self.decode(scenes)
        present, local = _factor(self.slots(idx))
        take = arrow_array(local, pa.int64())
        vals = [self.vals[s] for s in present]
        out = {}
        for name, typ in store.param_columns():
            if name in self.free_values:
                d, values = self.free_values[name]
                out[name] = arrow_array(values[idx[d]], typ)
            elif name != "Psi":
                out[name] = arrow_array([v[name] for v in vals], typ).take(take)
        if {"B2", "K2"} & set(self.free_values):
            col = {n: store.numpy_column(out[n]) for n in ("B2", "K2", "I2")}
            out["Psi"] = arrow_array(relative_damping(col["B2"], col["K2"], col["I2"]), pa.float64())
        else:
            out["Psi"] = arrow_array([S.psi_of(v) for v in vals], pa.float64()).take(take)
        return out

    def column(self, name: str, scenes: np.ndarray) -> np.ndarray:
        """One parameter's values at valid `scenes`, as NumPy."""
        if name in self.free_values:
            d, values = self.free_values[name]
            return values[self.decode(scenes)[d]]
        present, local = _factor(self.slots(self.decode(scenes)))
        return np.array([self.vals[s][name] for s in present])[local]

    # ---- model runs ----------------------------------------------------------------------
    def run_codes(self, idx: tuple, slot: np.ndarray) -> np.ndarray:
        """A number per valid scene, equal for two scenes exactly when their model keys are
        (params.model_key): its slot's key number, then the value of each free axis its key uses."""
        code = np.asarray(self._slot_key, dtype=np.int64)[slot] * self._free_size
        used_of = np.asarray(self._slot_used, dtype=np.int64)[slot]
        variants = np.unique(used_of)
        names = list(self._variants)
        for v in variants:
            sel = slice(None) if len(variants) == 1 else used_of == v
            stride = self._free_size
            for d in self.free:
                stride //= self.shape[d]
                ids = self._ids(d, names[v])
                if ids is not None:
                    code[sel] += ids[idx[d][sel]] * stride
        return code

    def _ids(self, d: int, used: tuple) -> np.ndarray | None:
        """Along free axis `d`: a number per position, equal where the values of its parameters
        in `used` are (None: the key uses none of them)."""
        names = tuple(n for n in self.spec.axes[d - 1].names if n in used)
        if not names:
            return None
        if (d, names) not in self._axis_ids:
            values = np.stack([self.free_values[n][1] for n in names], axis=1)
            _, inverse = np.unique(values, axis=0, return_inverse=True)
            self._axis_ids[(d, names)] = inverse.ravel().astype(np.int64)
        return self._axis_ids[(d, names)]
