"""The values a sweep spec gives (sweeps/README.md): one input checked, one axis expanded.

An input is a parameter of docs/model.md §12 or a derived one (Psi, relative damping); check_input
checks one value and returns it normalised. An axis is a list of values or a generated range,
`{linspace: [start, stop, num]}`, `{logspace: [start, stop, num]}` (geometric, both > 0) or
`{range: [start, stop, step]}` (stop included); generated values are rounded to 12 significant
digits, so 0.1 steps give 0.3. Every value is checked and must differ from the others. `Axis` is
one dimension of a sweep: a grid axis (one name) or a zip group (several names varying together).

SpecError, the error of everything wrong in a spec, is defined here, the lowest module that
raises it (spec.SpecError is the same class): it names the key, the value and what is allowed.
"""
from __future__ import annotations

import difflib
import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from fencesweep.errors import SpecError
from fencesweep.model import params as P

#: derived inputs: name -> (unit, meaning). Psi fixes K2 from B2 and I2 (docs/model.md §3).
DERIVED_INPUTS = {"Psi": ("-", "relative damping B2 / (2 sqrt(K2 I2)); fixes K2 = (B2 / (2 Psi))^2 / I2")}
INPUT_NAMES = P.NAMES + tuple(DERIVED_INPUTS)

AXIS_FORMS = ("linspace", "logspace", "range")
MAX_AXIS = 10_000_000
_SIG = 12  # generated axis values are rounded to 12 significant digits (0.1 steps give 0.3)
_ALLOWED = ("a list of values, {linspace: [start, stop, num]}, {logspace: [start, stop, num]} "
            "(geometric, both > 0) or {range: [start, stop, step]} (stop included)")


def did_you_mean(word: str, choices) -> str:
    """'; did you mean X?' for the closest of `choices`, or nothing."""
    near = difflib.get_close_matches(str(word), list(choices), n=1, cutoff=0.5)
    return f"; did you mean {near[0]!r}?" if near else ""


def round_value(x: float) -> float:
    """A generated or derived value rounded to 12 significant digits."""
    return float(f"{x:.{_SIG}g}")


def _known(name: str, where: str) -> None:
    if name not in INPUT_NAMES:
        raise SpecError(f"{where}: unknown parameter {name!r}{did_you_mean(name, INPUT_NAMES)} "
                        f"(parameters of docs/model.md §12: {', '.join(P.NAMES)}; derived: "
                        f"{', '.join(DERIVED_INPUTS)})")


def check_input(name: str, value: Any, where: str) -> Any:
    """Check one input value (a §12 parameter or a derived input); return it normalised."""
    _known(name, where)
    if isinstance(value, (list, dict)):
        raise SpecError(f"{where} = {value!r}: one value is expected here; axes go under grid or zip")
    numeric = name in DERIVED_INPUTS or P.BY_NAME[name].kind != "choice"
    if numeric and isinstance(value, str):
        try:  # YAML 1.1 reads 4e6 (no dot) as a string
            value = float(value)
        except ValueError:
            pass
    if name == "Psi":
        ok = (isinstance(value, (int, float)) and not isinstance(value, bool)
              and math.isfinite(value) and value > 0)
        if not ok:
            raise SpecError(f"{where}: Psi = {value!r} is not allowed: Psi must be a number with 0 < Psi")
        return float(value)
    try:
        return P.check_value(name, value)
    except P.ParameterError as exc:
        raise SpecError(f"{where}: {exc}") from None


def _form_args(form: str, args: Any, where: str) -> tuple:
    keys = ("start", "stop", "step") if form == "range" else ("start", "stop", "num")
    shape = f"{{{form}: [{', '.join(keys)}]}} or {{{form}: {{{': .., '.join(keys)}: ..}}}}"
    if isinstance(args, dict):
        bad = [k for k in args if k not in keys]
        if bad:
            raise SpecError(f"{where}.{form}: unknown key {bad[0]!r}{did_you_mean(bad[0], keys)}; "
                            f"expected {shape}")
        missing = [k for k in keys if k not in args]
        if missing:
            raise SpecError(f"{where}.{form}: missing {missing[0]!r}; expected {shape}")
        args = [args[k] for k in keys]
    if not isinstance(args, (list, tuple)) or len(args) != 3:
        raise SpecError(f"{where}.{form} = {args!r}: expected {shape}")
    out = []
    for k, a in zip(keys, args):
        x = P.as_finite_number(a)
        if x is None:
            raise SpecError(f"{where}.{form}: {k} = {a!r} is not a finite number; expected {shape}")
        out.append(x if isinstance(a, str) else a)  # a number stays as written (int or float)
    return tuple(out)


def axis_values(name: str, raw: Any, where: str) -> list:
    """Expand one axis (a list, or {linspace|logspace|range: ...}) and check every value."""
    _known(name, where)
    if isinstance(raw, list):
        if not raw:
            raise SpecError(f"{where} = []: the axis is empty; give at least one value ({_ALLOWED})")
        values = raw
    elif isinstance(raw, dict):
        values = _generated(name, raw, where)
    else:
        raise SpecError(f"{where} = {raw!r} is a single value: an axis is {_ALLOWED}; "
                        f"a fixed value goes under params")
    out = []
    for k, v in enumerate(values):
        out.append(check_input(name, v, f"{where}[{k}]"))
    if len(set(out)) != len(out):
        dup = next(v for v in out if out.count(v) > 1)
        raise SpecError(f"{where}: the value {dup!r} appears twice; every value of an axis must differ")
    return out


def _generated(name: str, raw: dict, where: str) -> list:
    """The values of {linspace|logspace|range: ...} (not yet checked)."""
    if len(raw) != 1:
        raise SpecError(f"{where} = {raw!r}: expected exactly one of {', '.join(AXIS_FORMS)}, "
                        f"got keys {', '.join(map(str, raw))}")
    form, args = next(iter(raw.items()))
    if form not in AXIS_FORMS:
        raise SpecError(f"{where}: unknown axis form {form!r}{did_you_mean(form, AXIS_FORMS)}; "
                        f"an axis is {_ALLOWED}")
    if name not in DERIVED_INPUTS and P.BY_NAME[name].kind == "choice":
        raise SpecError(f"{where}: {name} takes {P.BY_NAME[name].allowed()}, not a {form}; "
                        f"give a list, e.g. {list(P.BY_NAME[name].choices)}")
    a, b, n = _form_args(form, args, where)
    if form == "range":
        return _range(a, b, n, where)
    return _spaced(form, a, b, n, where)


def _spaced(form: str, a: float, b: float, n: Any, where: str) -> list:
    """linspace or logspace: `n` values from a to b."""
    if isinstance(n, float) and not n.is_integer():
        raise SpecError(f"{where}.{form}: num = {n!r} must be a whole number >= 1")
    n = int(n)
    if n < 1:
        raise SpecError(f"{where}.{form}: num = {n!r} gives an empty axis; num must be >= 1")
    if n > MAX_AXIS:
        raise SpecError(f"{where}.{form}: num = {n!r} is too large (at most {MAX_AXIS})")
    if form == "linspace":
        return [round_value(x) for x in np.linspace(a, b, n).tolist()]
    if a <= 0 or b <= 0:
        raise SpecError(f"{where}.logspace: start = {a!r}, stop = {b!r}: both must be > 0 "
                        f"(the endpoints are values, spaced geometrically, not exponents)")
    return [round_value(x) for x in np.geomspace(a, b, n).tolist()]


def _range(a: float, b: float, step: float, where: str) -> list:
    """range: start, start + step, ... up to stop included."""
    if step == 0:
        raise SpecError(f"{where}.range: step = 0 is not allowed; step must be non-zero")
    span = (b - a) / step
    if span < -1e-9:
        raise SpecError(f"{where}.range = [{a!r}, {b!r}, {step!r}] is empty: with step {step!r} "
                        f"stop must be {'>=' if step > 0 else '<='} start")
    count = int(math.floor(span + 1e-9)) + 1
    if count > MAX_AXIS:
        raise SpecError(f"{where}.range gives {count} values, too many (at most {MAX_AXIS})")
    return [round_value(a + k * step) for k in range(count)]


@dataclass(frozen=True)
class Axis:
    """One dimension of the sweep: a grid axis (one name) or a zip group (several names)."""

    names: tuple
    values: tuple  # values[k] is a tuple, one value per name
    where: str

    def __len__(self) -> int:
        return len(self.values)
