"""The `sensitivity:` section of a spec (`fencesweep sensitivity`, sweeps/README.md), checked:
each assumed input's range, the Saltelli base sample size n (a power of 2), the seed, the outputs
whose Sobol indices are wanted and the output file. design/sensitivity.py runs it.
"""
from __future__ import annotations

from typing import Any

from fencesweep.errors import SensitivityError
from fencesweep.model import params as P

OUTPUTS = ("worst_overload", "worst_deflection_max", "worst_residual_amplitude", "min_margin")
SECTION_KEYS = ("inputs", "n", "seed", "outputs", "output")


def _bounds(inputs: Any, spec) -> dict:
    if not isinstance(inputs, dict) or len(inputs) < 2:
        raise SensitivityError(f"sensitivity.inputs = {inputs!r}: expected at least two NAME: {{min: a, max: b}}")
    bounds = {}
    for name, rng in inputs.items():
        bounds[name] = _range(name, rng, spec)
    return bounds


def _range(name: str, rng: Any, spec) -> tuple:
    where = f"sensitivity.inputs.{name}"
    if name not in P.NAMES or P.BY_NAME[name].kind == "choice":
        raise SensitivityError(f"{where}: {name!r} is not a numeric parameter of docs/model.md §12")
    if name in spec.params or name in spec.envelope.names:
        raise SensitivityError(f"{where}: {name} is also fixed in params or the envelope; remove one of them")
    if not isinstance(rng, dict) or set(rng) != {"min", "max"}:
        raise SensitivityError(f"{where} = {rng!r}: expected {{min: a, max: b}}")
    lo, hi = rng["min"], rng["max"]
    for v, k in ((lo, "min"), (hi, "max")):
        try:
            P.check_value(name, float(v))
        except (P.ParameterError, TypeError, ValueError) as exc:
            raise SensitivityError(f"{where}.{k}: {exc}") from None
    if not float(lo) < float(hi):
        raise SensitivityError(f"{where}: min = {lo!r} must be < max = {hi!r}")
    return (float(lo), float(hi))


def parse_section(raw: Any, spec) -> dict:
    if not isinstance(raw, dict):
        raise SensitivityError(f"sensitivity = {raw!r}: expected a mapping with keys {', '.join(SECTION_KEYS)}")
    bad = [k for k in raw if k not in SECTION_KEYS]
    if bad:
        raise SensitivityError(f"sensitivity: unknown key {bad[0]!r} (allowed: {', '.join(SECTION_KEYS)})")
    if spec.envelope is None:
        raise SensitivityError("sensitivity: needs an envelope: section (the loads each sample point is judged over)")
    if spec.axes[:-1] or len(spec.cases) > 1:
        raise SensitivityError("sensitivity: the spec must fix its element (no grid, zip or cases besides the "
                               "envelope): the indices are those of one element")
    bounds = _bounds(raw.get("inputs"), spec)
    n = raw.get("n", 64)
    if isinstance(n, bool) or not isinstance(n, int) or n < 2 or n & (n - 1):
        raise SensitivityError(f"sensitivity.n = {n!r}: expected a power of 2 >= 2 (the Saltelli base sample)")
    seed = raw.get("seed", 0)
    if isinstance(seed, bool) or not isinstance(seed, int) or seed < 0:
        raise SensitivityError(f"sensitivity.seed = {seed!r}: expected a whole number >= 0")
    outputs = raw.get("outputs", ["worst_overload", "worst_deflection_max"])
    if not isinstance(outputs, list) or not outputs or any(o not in OUTPUTS for o in outputs):
        raise SensitivityError(f"sensitivity.outputs = {outputs!r}: expected a list among {', '.join(OUTPUTS)}")
    output = raw.get("output", "results/sensitivity.parquet")
    if not isinstance(output, str) or not output.endswith(".parquet"):
        raise SensitivityError(f"sensitivity.output = {output!r}: expected a path ending in .parquet")
    return {"bounds": bounds, "n": n, "seed": seed, "outputs": outputs, "output": output}
