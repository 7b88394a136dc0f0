"""A spec's scenes as whole columns: resolved once per combination of the values that params.resolve
reads together, the rest laid out by index (sweep/plan.py plans with it, sweep/assemble.py writes
the table's parameter columns with it, the workers resolve their chunks' runs with it).

params.resolve checks most parameters one by one and copies them (params.ALONE); only a few enter
a derived value or a combination check (the load's start, docs/model.md §1; I2 and t_max, §3 and
§12; Psi -> K2, §3). A spec's dimensions (its cases, then its axes, spec.Spec.decode) therefore
split in two: the *free* axes, whose parameters are all in ALONE, and the *core* dimensions, the
rest. resolve runs once per combination of core values (a *slot*, numbered by its flat index over
the core dimensions: the envelope study has 64, for its 64 loads, not 419,904 scenes), and a
scene's column is its slot's value, or its free axis's value at its index. The same split gives
each scene's model run (params.model_key, keys): its slot's key without the free axes' values, as
a 16-byte digest, and the index of each free axis's value that the key uses, as one number.

Nothing here loops over scenes in Python, and nothing kept grows with the scenes: the slots
resolved are held in a cache of at most HELD (a spec whose every scene is its own slot resolves
each once per pass, as scene by scene).
"""
from __future__ import annotations

import hashlib
import io
import math
import pickle
from collections import OrderedDict

import numpy as np
import pyarrow as pa

from fencesweep.model import params as P
from fencesweep.study.spec import spec as S
from fencesweep.study.store import table as store
from fencesweep.study.store.columns import arrow_array

#: slots held resolved (an LRU cache): ~2 KB each, so at most ~130 MB
HELD = 65_536
#: a dense table of the core combinations is used up to this size (else np.unique sorts them)
_DENSE_SLOTS = 1 << 20
_CHOICES = tuple(p.name for p in P.TABLE if p.kind == "choice")


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


def _shared(values: list) -> bool:
    """Whether the values are all the first, a float's sign included (0.0 and -0.0 differ)."""
    first = values[0]
    if values.count(first) != len(values):
        return False
    return not isinstance(first, float) or first != 0.0 or len({math.copysign(1.0, x) for x in values}) == 1


class Slot:
    """One combination of core values, resolved: its parameter set (None: invalid), the digest of
    its model key without the free axes' values and the number of the free parameters its key uses."""

    __slots__ = ("vals", "digest", "variant")

    def __init__(self, vals: dict | None, digest: bytes, variant: int):
        self.vals, self.digest, self.variant = vals, digest, variant


class Scenes:
    """The scenes of `spec` as columns (module docstring)."""

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
        self.free_size = math.prod(self.shape[d] for d in self.free)
        self._held: OrderedDict = OrderedDict()  # core flat index -> Slot
        self._variants: dict = {}  # the free parameters a key uses -> their number
        self._axis_ids: dict = {}

    # ---- scenes -> slots -----------------------------------------------------------------
    def decode(self, scenes: np.ndarray) -> tuple:
        """Scene numbers -> their index along each dimension (spec.Spec.decode, on arrays)."""
        return np.unravel_index(np.asarray(scenes, dtype=np.int64), self.shape)

    def slots(self, idx: tuple) -> tuple:
        """(the Slots present among the scenes of `idx` (decode), each scene's position among them),
        the Slots in order of their core flat index, which is the order of their first scenes."""
        core = [idx[d] for d in self.core]
        flat = np.ravel_multi_index(core, self.core_shape) if len(core) > 1 else np.asarray(core[0], np.int64)
        size = math.prod(self.core_shape)
        if size <= max(len(flat), _DENSE_SLOTS):
            present = np.flatnonzero(np.bincount(flat, minlength=size))
            lut = np.zeros(size, dtype=np.int64)
            lut[present] = np.arange(len(present))
            local = lut[flat]
        else:
            present, local = np.unique(flat, return_inverse=True)
            local = local.ravel()
        return [self._slot(int(u)) for u in present], local

    def _slot(self, flat: int) -> Slot:
        """The Slot of core combination `flat` (its free axes at their first value), resolved if it
        is not held."""
        slot = self._held.get(flat)
        if slot is not None:
            self._held.move_to_end(flat)
            return slot
        where = dict(zip(self.core, np.unravel_index(flat, self.core_shape)))
        scene = int(np.ravel_multi_index([int(where.get(d, 0)) for d in range(len(self.shape))], self.shape))
        try:
            vals = self.spec.resolve(scene)
        except P.ParameterError:
            slot = Slot(None, bytes(16), -1)
        else:
            key = P.model_key(vals)
            used = tuple(e[0] for e in key[1:] if e[0] in self.free_values)
            core = (key[0], tuple(e for e in key[1:] if e[0] not in self.free_values), used)
            slot = Slot(vals, hashlib.blake2b(key_bytes(core), digest_size=16).digest(),
                        self._variants.setdefault(used, len(self._variants)))
        self._held[flat] = slot
        if len(self._held) > HELD:
            self._held.popitem(last=False)
        return slot

    # ---- model runs ----------------------------------------------------------------------
    def keys(self, scenes: np.ndarray) -> tuple:
        """For the scenes `scenes`: (whether each resolves, the 16-byte digest of its slot's key
        (module docstring), the number of the free axes' values its key uses, {variant (scene,
        drive, contact_law, profile): its first scene here}). Two valid scenes share a model run
        exactly when both their digests and their numbers are equal."""
        scenes = np.asarray(scenes, dtype=np.int64)
        idx = self.decode(scenes)
        slots, local = self.slots(idx)
        valid = np.array([s.vals is not None for s in slots], dtype=bool)[local]
        digest = np.frombuffer(b"".join(s.digest for s in slots), dtype="V16")[local]
        variant = np.array([s.variant for s in slots], dtype=np.int64)[local]
        firsts: dict = {}
        _, at = np.unique(local, return_index=True)
        for s, k in zip(slots, at.tolist()):
            if s.vals is not None:
                firsts.setdefault((self.spec.scene,) + tuple(s.vals[c] for c in _CHOICES), int(scenes[k]))
        return valid, digest, self._free_code(idx, variant), firsts

    def _free_code(self, idx: tuple, variant: np.ndarray) -> np.ndarray:
        """Per scene, the values of the free axes that its key uses, as one number (mixed radix)."""
        code = np.zeros(len(variant), dtype=np.int64)
        names = list(self._variants)
        for v in np.unique(variant[variant >= 0]):
            sel = variant == v
            stride = self.free_size
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

    # ---- columns -------------------------------------------------------------------------
    def columns(self, scenes: np.ndarray) -> dict:
        """The table's label, parameter and derived columns (store.param_columns) of valid
        `scenes`, as Arrow arrays."""
        idx = self.decode(scenes)
        slots, local = self.slots(idx)
        take = arrow_array(local, pa.int64())
        vals = [s.vals for s in slots]
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
        idx = self.decode(scenes)
        if name in self.free_values:
            d, values = self.free_values[name]
            return values[idx[d]]
        slots, local = self.slots(idx)
        return np.array([s.vals[name] for s in slots])[local]

    def value_columns(self, scenes, names) -> dict:
        """The parameters `names` of the valid `scenes`' resolved sets (resolved) as columns, for
        prepare.prepare_columns: a free axis's values as float64; a value the scenes' slots share,
        as itself; else an array over the scenes (float64 for numbers, objects otherwise)."""
        idx = self.decode(scenes)
        slots, local = self.slots(idx)
        out = {}
        for name in names:
            if name in self.free_values:
                d, values = self.free_values[name]
                out[name] = values[idx[d]]
                continue
            col = [s.vals[name] for s in slots]
            if _shared(col):
                out[name] = col[0]
            elif all(isinstance(x, (int, float)) and not isinstance(x, bool) for x in col):
                out[name] = np.array(col, dtype=np.float64)[local]
            else:
                objects = np.empty(len(col), dtype=object)
                objects[:] = col
                out[name] = objects[local]
        return out

    def resolved(self, scenes) -> list:
        """spec.resolve of each of the valid `scenes`: its slot's parameter set with its free axes'
        values in place, which is what resolve gives (params.ALONE)."""
        idx = self.decode(scenes)
        slots, local = self.slots(idx)
        free = [(n, values[idx[d]].tolist()) for n, (d, values) in self.free_values.items()]
        out = []
        for k, at in enumerate(local.tolist()):
            vals = dict(slots[at].vals)
            for name, col in free:
                vals[name] = col[k]
            out.append(vals)
        return out
