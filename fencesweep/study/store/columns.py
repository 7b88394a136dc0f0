"""NumPy columns to Arrow arrays and back, without a copy where the types allow (float64,
int64 without nulls): a table is built from, and read into, plain buffers (store/table.py)."""
from __future__ import annotations

import numpy as np
import pyarrow as pa

#: Arrow types built from, and read into, NumPy buffers directly (arrow_array, numpy_column)
_NUMPY_OF = {pa.float64(): np.float64, pa.int64(): np.int64}


def arrow_array(values, typ: pa.DataType) -> pa.Array:
    """`values` (a sequence or NumPy array) as an Arrow array of type `typ`, made from NumPy
    buffers (pa.Array.from_buffers) for float64 (None a null), int64, bool and string values.

    pa.array would do the same, but its first call in a process imports pandas (0.2 s,
    measured), which a sweep's workers and its planning never need: with this, the main job's
    processes never import it. Other types and other values go through pa.array."""
    if isinstance(values, (pa.Array, pa.ChunkedArray)):
        return values if values.type == typ else values.cast(typ)
    n = len(values)
    if typ == pa.bool_():
        arr = np.asarray(values)
        if arr.dtype.kind == "b":
            return pa.Array.from_buffers(typ, n, [None, pa.py_buffer(np.packbits(arr, bitorder="little"))])
    elif typ in _NUMPY_OF and n:
        arr, valid = _with_nulls(values) if typ == pa.float64() else (np.asarray(values), None)
        if arr.dtype.kind in ("iu" if typ == pa.int64() else "fiu"):
            data = pa.py_buffer(np.ascontiguousarray(arr, _NUMPY_OF[typ]))
            return pa.Array.from_buffers(typ, n, [valid, data], null_count=-1 if valid else 0)
    elif typ == pa.string():
        made = _few_strings(values, n) if n > _FEW else None
        if made is not None:
            return made
        if all(isinstance(v, str) or v is None for v in values):
            return _strings(values, n)
    return pa.array(values, type=typ)


#: string columns longer than this are made from their distinct values (_few_strings)
_FEW = 32


def _strings(values, n: int) -> pa.Array:
    """Strings (or None, a null) as an Arrow string array, from its buffers."""
    data = [b"" if v is None else v.encode() for v in values]
    offsets = np.zeros(n + 1, np.int32)
    np.cumsum([len(b) for b in data], out=offsets[1:])
    missing = np.array([v is None for v in values], dtype=bool)
    valid = pa.py_buffer(np.packbits(~missing, bitorder="little")) if missing.any() else None
    return pa.Array.from_buffers(pa.string(), n, [valid, pa.py_buffer(offsets), pa.py_buffer(b"".join(data))],
                                 null_count=-1 if valid else 0)


def _few_strings(values, n: int) -> pa.Array | None:
    """A long column of a few distinct strings (a sweep's outcome, status, case): its distinct
    values made once (_strings) and taken by each entry's number among them, the loops over the
    entries in C (set, map); the same array as _strings gives. None where the values are not
    all strings or None, or not hashable, or mostly distinct (the caller makes them one by one)."""
    try:
        distinct = list(set(values))
    except TypeError:  # unhashable values: not strings
        return None
    if len(distinct) > n // 4 or not all(isinstance(v, str) or v is None for v in distinct):
        return None
    number = {v: k for k, v in enumerate(distinct)}
    which = np.fromiter(map(number.__getitem__, values), np.int32, n)
    return _strings(distinct, len(distinct)).take(pa.Array.from_buffers(pa.int32(), n, [None, pa.py_buffer(which)]))


def _with_nulls(values) -> tuple:
    """(float values as a NumPy array, Arrow validity bitmap or None): None is a null (a
    parameter a scene leaves unset); values that are not all numbers come back as an object
    array, for pa.array to take."""
    arr = np.asarray(values)
    if arr.dtype != object:
        return arr, None
    missing = np.array([v is None for v in values], dtype=bool)
    if not all(isinstance(v, (float, int)) for v, m in zip(values, missing) if not m):
        return arr, None
    valid = pa.py_buffer(np.packbits(~missing, bitorder="little")) if missing.any() else None
    return np.where(missing, 0.0, arr).astype(np.float64), valid


def numpy_column(col) -> np.ndarray:
    """An Arrow column (Array or ChunkedArray) as a NumPy array (strings as an object array),
    read from its buffers for the types arrow_array makes (see there: to_numpy's first call
    imports pandas); other types, and columns with nulls, through to_numpy."""
    chunks = col.chunks if isinstance(col, pa.ChunkedArray) else [col]
    parts = [_numpy_chunk(c) for c in chunks]
    if len(parts) == 1:
        return parts[0]
    if not parts:
        return np.empty(0, _NUMPY_OF.get(col.type, bool if col.type == pa.bool_() else object))
    return np.concatenate(parts)


def _numpy_chunk(arr: pa.Array) -> np.ndarray:
    n, off = len(arr), arr.offset
    if n and arr.null_count == 0 and arr.type in _NUMPY_OF:
        dt = np.dtype(_NUMPY_OF[arr.type])
        return np.frombuffer(arr.buffers()[1], dt, count=n, offset=off * dt.itemsize)
    if n and arr.null_count == 0 and arr.type == pa.bool_():
        bits = np.frombuffer(arr.buffers()[1], np.uint8)
        return np.unpackbits(bits, count=off + n, bitorder="little")[off:].astype(bool)
    if arr.null_count == 0 and arr.type == pa.string():
        return np.array(arr.to_pylist(), dtype=object)
    return arr.to_numpy(zero_copy_only=False)


# ---------------------------------------------------------------------------- schema
