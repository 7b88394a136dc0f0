"""The spec reference page (spec.md), written when the site is built (hooks.py).

Every key a spec reader accepts is read from the reader itself (the key tuples of
fencesweep/study/spec/, the fields of design.Limits, the parameter table of model/params.py), and
every default is what the reader makes of a spec that leaves the key out: a minimal spec of each
kind is parsed and its values read back. Only the type and the meaning of a spec key are written
here; a key the reader accepts without a row below, or a row for a key it no longer accepts, stops
the build (`check`), so the page cannot drift from the code.
"""
from __future__ import annotations

import dataclasses

#: a default that is not one value: the key is required, or its default is described in words
REQUIRED = "required"


def _examples() -> dict:
    """The parsed minimal specs whose values are the readers' defaults."""
    from fencesweep.study.spec import file as F
    from fencesweep.study.spec import risk as R

    env = {"L": {"min": 0.2, "max": 0.7}}
    design = F.parse({"envelope": env, "design": {"variables": {"B2": {"min": 0, "max": 600}}}})
    inputs = {"k1": {"min": 2.0e6, "max": 8.0e6}, "e": {"min": 0.1, "max": 0.4}}
    sens = F.parse({"envelope": env, "sensitivity": {"inputs": inputs}})
    size = {"min": 0.1, "max": 0.2}
    risk = R.parse({"elements": {"B2": [72.0]}, "population": {"L": size, "A": size, "m1": {"min": 5, "max": 15}}})
    return {"spec": F.parse({}), "envelope": design.envelope, "design": design.design,
            "sensitivity": sens.sensitivity, "risk": risk, "population": risk.population}


def _one_of(values) -> str:
    return " \\| ".join(f"`{v}`" for v in values)


def _at(kind: str, *path: str, none: str | None = None):
    """The default of a key: read from the parsed example of `kind` along `path` (attributes, or keys of a
    dict); `none`, the text for a None there."""
    def read(examples: dict):
        value = examples[kind]
        for step in path:
            value = value[step] if isinstance(value, dict) else getattr(value, step)
        return none if value is None and none is not None else value

    return read


#: the default of deflection_max, None in the readers
PER_SCENE = "`dalpha_perm` (each scene's)"


def _sections() -> list:
    """(title, intro, the keys the reader accepts, rows): a row is (key, type, default, meaning), the
    default a function of the parsed examples, or text."""
    from fencesweep.model import params as P
    from fencesweep.study.spec import design as D
    from fencesweep.study.spec import envelope as E
    from fencesweep.study.spec import population as PO
    from fencesweep.study.spec import risk as R
    from fencesweep.study.spec import sensitivity as SA
    from fencesweep.study.spec import spec as S
    from fencesweep.study.spec.axes import AXIS_FORMS

    axis = "a list, or " + ", ".join(f"`{{{f}: [...]}}`" for f in AXIS_FORMS)
    limits = [f.name for f in dataclasses.fields(D.Limits)]
    return [
        ("Sweep spec: `fencesweep grid`", "The top level of a sweep spec ([The spec](sweeps.md#the-spec)).",
         S.TOP_KEYS, [
            ("description", "text", _at("spec", "description"), "free text, kept in the table's metadata"),
            ("scene", _one_of(P.SCENES), _at("spec", "scene"),
             "the scene every run simulates (docs/model.md §8, §14)"),
            ("case", _one_of(P.CASES), _at("spec", "case"), "a named case as the base of every scene"),
            ("params", "mapping PARAMETER: value", "none",
             "fixed values for every scene (the parameters below, and `Psi`)"),
            ("grid", f"mapping PARAMETER: axis ({axis})", "none", "axes crossed with each other (Cartesian product)"),
            ("zip", "mapping PARAMETER: axis, or a list of them", "none",
             "axes of equal length that vary together; several groups are crossed with each other and `grid`"),
            ("cases", "list of named cases or mappings of parameters (with `case: NAME` optionally)", "none",
             "parameter sets crossed with all the axes, outermost"),
            ("output", "path", "`SPEC.parquet` after the spec's file (`sweep.parquet` without one)",
             "the table, relative to the current directory; `--out` overrides it"),
            ("invalid", _one_of(S.INVALID_POLICIES), _at("spec", "invalid"),
             "a scene that cannot start: `error` stops the command, `skip` leaves it out and counts it"),
            ("chunk_size", "integer", "sized from a timed sample", "model runs per chunk"),
            ("loads", "list of named cases or mappings of " + ", ".join(f"`{n}`" for n in P.LOAD_NAMES), "none",
             "`scene: stream` only: one load per cycle, for every scene; `n_cycles` is then its length"),
            ("envelope", "mapping", "none", "loads sampled from ranges, the innermost axis (`envelope:` below)"),
            ("design", "mapping", "none", "the search of `fencesweep design` (`design:` below)"),
            ("sensitivity", "mapping", "none", "the Sobol indices of `fencesweep sensitivity` (`sensitivity:` below)"),
        ]),
        ("`envelope:`", "Sampled loads ([Envelopes](sweeps.md#envelopes-design-for-every-package)). Besides the "
         "keys below, any parameter of the table at the end, normally `L`, `A`, `m1`, `dP`, `R_s`, `phi0`: "
         "`{min: a, max: b}` (a range), a list (choices), one value, or `across` for `dP` (anywhere across the "
         "belt).", E.SAMPLE_KEYS, [
            ("corners", "boolean", _at("envelope", "corners"), "the box's corners: 2^ranges x choices loads"),
            ("sobol", "integer", _at("envelope", "n"), "plus N scrambled Sobol points (scipy.stats.qmc)"),
            ("lhs", "integer", _at("envelope", "n"), "instead of `sobol`: N Latin-hypercube points"),
            ("seed", "integer", _at("envelope", "seed"), "the sample's seed"),
            ("invalid", "`error` \\| `skip`", _at("envelope", "invalid"),
             "a load that cannot start on the belt: `error` stops the spec naming it, `skip` drops it and says so"),
        ]),
        ("`design:`", "The search of `fencesweep design` "
         "([design](sweeps.md#fencesweep-design-specyaml---out-dir---jobs-n)); needs an `envelope:`.", D.SECTION_KEYS, [
            ("variables", "mapping PARAMETER: `{min: a, max: b}`", REQUIRED, "the design variables and their ranges"),
            ("constraints", "mapping", "below", "the limits every load must keep (`design.constraints`)"),
            ("objective", _one_of(D.OBJECTIVES), _at("design", "objective"),
             "what the search maximises (the smallest margin) or minimises"),
            ("optimizer", "mapping", "below", "differential evolution's settings (`design.optimizer`)"),
            ("verify", "mapping", "below", "the fresh, denser sample the optimum is checked on (`design.verify`)"),
            ("compare", "mapping NAME: `{PARAMETER: value}`", lambda examples: list(examples["design"].compare),
             "elements judged beside the recommendation on the fresh sample"),
            ("output", "directory", _at("design", "output"), "where recommended.json and the tables go"),
            ("digits", "integer", _at("design", "digits"), "significant digits the optimum is rounded to"),
            ("prefer", "`{VARIABLE: min}` \\| `{VARIABLE: max}`", _at("design", "prefer"),
             "then, among points within `within` of the best margin, the least (most) VARIABLE "
             "(objective `max_min_margin` only)"),
            ("within", "number", _at("design", "within"), "the margin band of `prefer`"),
        ]),
        ("`design.constraints:`", "The limits of a design (and of an envelope sweep's points table).", limits, [
            ("scraped", "boolean", _at("design", "limits", "scraped"), "every load must be scraped"),
            ("overload", "number", _at("design", "limits", "overload"), "the worst overload must stay <= this"),
            ("deflection_max", "number [rad] \\| `dalpha_perm`",
             _at("design", "limits", "deflection_max", none=PER_SCENE),
             "the worst deflection_max must stay <= this"),
            ("residual_amplitude", "number [rad] \\| `null`", _at("design", "limits", "residual_amplitude"),
             "the worst residual_amplitude must stay <= this (1 deg: the fence is home); `null`: not constrained"),
        ]),
        ("`design.optimizer:`", "scipy's `differential_evolution`, seeded, then a bounded Nelder-Mead.",
         D.OPTIMIZER_KEYS, [
            ("seed", "integer", _at("design", "seed"), "the optimiser's seed"),
            ("maxiter", "integer", _at("design", "maxiter"), "generations at most"),
            ("popsize", "integer", _at("design", "popsize"), "population size multiplier (scipy's `popsize`)"),
            ("tol", "number", _at("design", "tol"), "relative tolerance of convergence"),
            ("refine", "integer", _at("design", "refine"),
             "Nelder-Mead evaluations on the fresh sample (0: none)"),
        ]),
        ("`design.verify:`", "The fresh sample of the same envelope the optimum is judged on.", D.VERIFY_KEYS, [
            ("sobol", "integer", _at("design", "verify_n"), "N scrambled Sobol points"),
            ("lhs", "integer", "none", "instead of `sobol`: N Latin-hypercube points"),
            ("seed", "integer", _at("design", "verify_seed"), "the sample's seed (not the envelope's)"),
        ]),
        ("`sensitivity:`", "Sobol indices of `fencesweep sensitivity` (needs SALib); needs an `envelope:` and a "
         "fixed element.", SA.SECTION_KEYS, [
            ("inputs", "mapping PARAMETER: `{min: a, max: b}`, at least two", REQUIRED, "the assumed inputs' ranges"),
            ("n", "integer, a power of 2", _at("sensitivity", "n"),
             "Saltelli base sample: n (d + 2) input sets"),
            ("seed", "integer", _at("sensitivity", "seed"), "the sample's seed"),
            ("outputs", "list among " + _one_of(SA.OUTPUTS), _at("sensitivity", "outputs"),
             "the results whose indices are wanted"),
            ("output", "path ending in .parquet", _at("sensitivity", "output"), "the indices table"),
        ]),
        ("Risk spec: `fencesweep risk`", "The top level of a risk spec "
         "([Risk from a parcel mix](sweeps.md#risk-from-a-parcel-mix-fencesweep-risk)).", R.TOP_KEYS, [
            ("description", "text", _at("risk", "description"), "free text, kept in the table's metadata"),
            ("params", "mapping PARAMETER: value", "none", "fixed inputs of every cycle"),
            ("elements", "axes as in `grid` (crossed), or a list of `{PARAMETER: value}`", REQUIRED,
             "the elements, e.g. B2 x K2"),
            ("compare", "mapping NAME: `{PARAMETER: value}`", "none", "named elements, marked on the map and reported"),
            ("operating", "`{t_c: .., v: ..}` or a list of them", "the params' t_c and v",
             "the operating points every element meets"),
            ("population", "mapping", REQUIRED, "the parcel mix (`population:` below)"),
            ("risk", "mapping", "below", "the sampling and the limits (`risk:` below)"),
            ("output", "path", "`SPEC.parquet` after the spec's file (`risk.parquet` without one)", "the table"),
        ]),
        ("`risk:`", "The looks and the decision against p_max.", R.RISK_KEYS, [
            ("p_max", "number in (0, 1)", _at("risk", "p_max"), "the acceptable P(any constraint broken)"),
            ("confidence", "number in (0, 1)", _at("risk", "confidence"),
             "the level the intervals of all a unit's looks hold together"),
            ("first", "integer", _at("risk", "first"), "parcels at the screening look"),
            ("growth", "number > 1", _at("risk", "growth"), "each later look's size over the last's (from the least size at which no failure decides below p_max)"),
            ("cap", "integer", _at("risk", "cap"), "parcels at most per element and operating point"),
            ("limits", "mapping", "below", "what counts as broken (`risk.limits`)"),
            ("samples", "boolean", _at("risk", "samples"), "also write `OUT_samples.parquet`, one row per cycle"),
        ]),
        ("`risk.limits:`", "A cycle breaks a constraint when its result exceeds the limit.", R.LIMIT_KEYS, [
            ("overload", "number", _at("risk", "limits", "overload"), "overload above this is `overload`"),
            ("deflection_max", "number [rad] \\| `dalpha_perm`",
             _at("risk", "limits", "deflection_max", none=PER_SCENE),
             "deflection_max above this is `deflection`"),
            ("residual_amplitude", "number [rad]", _at("risk", "limits", "residual_amplitude"),
             "residual_amplitude above this is `residual` (1 deg)"),
        ]),
        ("`population:`", "The parcels, drawn with numpy's PCG64, one stream per column, seeded. A size or a "
         "placement is `{dist: NAME, PARAMETER: value, ..., min: a, max: b}` (a scipy.stats distribution "
         "truncated to [a, b]) or `{min: a, max: b}` (uniform).", PO.KEYS, [
            ("parcels", "path (CSV or Parquet with columns " + ", ".join(f"`{n}`" for n in PO.SIZES) + ")", "none",
             "measured parcels drawn with replacement, instead of the sizes' distributions"),
            ("L", "distribution [m]", REQUIRED + " (or `parcels`)", "the parcel's length"),
            ("A", "distribution [m]", REQUIRED + " (or `parcels`)", "the parcel's width"),
            ("m1", "distribution [kg]", REQUIRED + " (or `parcels`)", "the parcel's mass"),
            ("dP", "`across` or a distribution of the fraction of the room", _drawn("dP"),
             "uniform across the part of the belt where the parcel fits"),
            ("R_s", "distribution [m]", _drawn("R_s"),
             "the leading edge's x when the drive starts: the trigger window"),
            ("phi0", "number [rad]", "the params' `phi0`", "the parcels' orientation (one value)"),
            ("seed", "integer", _at("population", "seed"), "the draws' seed"),
            ("too_large", "`error` \\| `skip`", _at("population", "too_large"),
             "a parcel wider than the belt: `error` refuses the spec, `skip` leaves it out and counts it"),
        ]),
    ]


def _drawn(name: str):
    """The default of a placement column of the population, as the spec would write it."""
    def read(examples: dict) -> str:
        column = examples["population"].columns[name]
        if column.kind == "dist" and column.dist == "uniform":
            return f"`{{min: {column.lo:g}, max: {column.hi:g}}}`"
        return column.definition()

    return read


def check(sections: list) -> None:
    """Raise ValueError unless every section's rows are exactly the keys its reader accepts."""
    for title, _, keys, rows in sections:
        written = [r[0] for r in rows]
        missing = [k for k in keys if k not in written]
        extra = [k for k in written if k not in keys]
        if missing or extra:
            raise ValueError(f"docs/gen/spec_ref.py, section {title}: the spec reader accepts keys without a row "
                             f"here: {missing}; rows for keys it does not accept: {extra}")


def value_text(value) -> str:
    """A default as the spec would write it, in backticks."""
    if value is None:
        return "none"
    if isinstance(value, bool):
        return f"`{str(value).lower()}`"
    if isinstance(value, float):
        return f"`{value:g}`"
    if isinstance(value, (list, tuple)):
        return ", ".join(value_text(v) for v in value)
    if value == "":
        return '`""`'
    if isinstance(value, str) and value.startswith("`"):  # a text that is already Markdown
        return value
    return f"`{value}`"


def _cell(text: str) -> str:
    return str(text).replace("\n", " ")


def section_lines(section: tuple, examples: dict) -> list:
    title, intro, _, rows = section
    out = [f"## {title}", "", intro, "", "| key | type | default | meaning |", "|---|---|---|---|"]
    for key, kind, default, meaning in rows:
        if callable(default):
            default = value_text(default(examples))
        out.append(f"| `{key}` | {_cell(kind)} | {_cell(default)} | {_cell(meaning)} |")
    return out + [""]


def _param_default(p) -> str:
    if p.default is None:
        return "derived"
    return value_text(p.default)


def parameter_lines() -> list:
    """The parameter table of docs/model.md §12, from model/params.py, and the derived input Psi."""
    from fencesweep.model import params as P
    from fencesweep.study.spec.axes import DERIVED_INPUTS

    out = ["## Parameters", "",
           "The names of `params:`, `grid:`, `zip:`, `cases:`, `envelope:`, `elements:` and `design.variables:` "
           "(docs/model.md §12; read from `fencesweep.model.params.TABLE`). Units are SI, angles in radians; "
           "derived: computed from the others unless given.", "",
           "| parameter | unit | default | allowed | meaning |", "|---|---|---|---|---|"]
    for p in P.TABLE:
        what = p.doc + (" (an engine setting)" if p.numerics else "")
        out.append(f"| `{p.name}` | {p.unit} | {_param_default(p)} | {_cell(p.allowed())} | {_cell(what)} |")
    for name, (unit, doc) in DERIVED_INPUTS.items():
        out.append(f"| `{name}` | {unit} | derived | a number with 0 < {name} | {_cell(doc)}; not with K2 |")
    cases = "; ".join(f"`{n}`: " + ", ".join(f"{k} = {v:g}" for k, v in c.items()) for n, c in P.CASES.items())
    return out + ["", f"Named cases: {cases}.", ""]


def page() -> str:
    """The whole page; ValueError when a key is not described (check)."""
    sections = _sections()
    check(sections)
    examples = _examples()
    lines = ["# Spec reference", "",
             "Every key of the YAML specs, generated from the spec readers in `fencesweep/study/spec/` when this "
             "site is built: the keys are those the readers accept, the defaults what they make of a spec that "
             "leaves the key out. Every key is optional unless its default says *required*. The prose, with "
             "examples, is in [Sweeps and specs](sweeps.md).", ""]
    for section in sections:
        lines += section_lines(section, examples)
    return "\n".join(lines + parameter_lines())

