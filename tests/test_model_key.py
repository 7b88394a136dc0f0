"""params.model_key, the sweep's de-duplication key, as a property.

A sweep simulates each key once and fills every scene with that key from the one run
(docs/model.md §8: model only what a scene needs). If two parameter sets that differ in a
parameter the scene uses shared a key, one of them would silently get the other's results.
For every scene and every parameter of docs/model.md §12 (and the engine settings), hypothesis
draws a parameter set and a second one that differs in that parameter alone, and checks

* a parameter the scene uses (USES below, written from docs/model.md, not from params.py)
  changes the key;
* whenever the keys are equal, the engine's results are equal too: the engine itself is
  the judge of what a model reads, so a parameter missing from USES is caught as well.
"""
import functools
import math

import pytest
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st

from fencesweep.model import params as P
from fencesweep import simulate_resolved

#: draws around the defaults, inside docs/model.md §12's bounds, so that each run stays short
RANGES = {
    "v": (0.5, 3.0), "P_max": (0.7, 1.0), "mu1": (0.0, 0.8), "mu2": (0.0, 0.8), "L": (0.05, 0.7),
    "A": (0.01, 0.3), "m1": (1.0, 30.0), "dP": (0.0, 0.3), "R_s": (-0.5, 0.5), "phi0": (-0.3, 0.3),
    "k1": (1e6, 1e7), "k_lin": (1e5, 1e7), "l": (1.0, 1.5), "m2": (1.0, 10.0), "I2": (1.0, 5.0),
    "B2": (0.0, 150.0), "K2": (0.0, 1500.0), "t_c": (1.0, 2.0), "swing": (0.65, 0.85),
    "coupler_ratio": (1.5, 4.0), "H": (0.1, 0.5), "dalpha_perm": (0.1, 0.5), "R": (0.5, 1.5),
    "w": (0.5, 3.0), "eps_v": (1e-4, 1e-2), "t_max": (1.5, 3.0), "step_factor": (0.5, 2.0),
    "dt": (1e-4, 1e-3), "n_cycles": (1, 2), "period": (1.0, 3.0),
}
RESTITUTIONS = (0.2, 0.5, 0.9)  # each new e costs a calibration of q(e) (~0.1 s)


def test_ranges_cover_every_parameter():
    numeric = {p.name for p in P.TABLE if p.kind != "choice"}
    assert numeric - {"e"} == set(RANGES)


@functools.cache
def value(name: str):
    """A strategy for one parameter's value (None = derived, for the derived ones); one object per
    parameter, made once (a new strategy per draw was half the file's time)."""
    p = P.BY_NAME[name]
    if p.kind == "choice":
        return st.sampled_from(p.choices)
    if name == "e":
        return st.sampled_from(RESTITUTIONS)
    if p.kind == "int":  # n_cycles: streams of one or two cycles keep each run short
        return st.one_of(st.none(), st.integers(*RANGES[name]))
    drawn = st.floats(*RANGES[name], allow_nan=False)
    return st.one_of(st.none(), drawn) if p.derived else drawn


#: a value of every parameter, drawn in one draw (each value as `value` draws it)
EVERY_PARAMETER = st.fixed_dictionaries({n: value(n) for n in P.NAMES})


def uses(scene: str, vals: dict, given: dict) -> set:
    """The parameters the scene's model reads (docs/model.md §3, §4, §5, §7, §8, §11, §12), for the
    resolved set `vals` whose explicit inputs were `given`."""
    law = {"m1", "e", "k1", "contact_law"} | ({"k_lin"} if vals["contact_law"] == "linear" else set())
    # the engine stops a run whose penetration exceeds half the load's smaller side (§5), in
    # every scene: L and A bound the impact and the free fall too
    bound = {"L", "A"}
    drive = vals["drive"]
    # I2 = m2 l^2/3 unless given (§3): m2 (and l, where only I2 matters) act through it
    inertia = {"I2"} | (set() if given.get("I2") is not None else {"m2", "l"})
    if scene == "freefall":  # §7: the load dropped from H onto a rigid surface
        return law | bound | {"H", "step_factor"}
    if scene == "impact":  # §8: a point hitting the fence at R with speed w; drive at rest
        fence = set() if drive == "rigid" else inertia | ({"B2", "K2"} if drive == "flexible" else set())
        return law | bound | fence | {"R", "w", "step_factor"}
    used = set(P.NAMES) - {"R", "w", "dt", "m2", "I2", "B2", "K2", "k_lin", "coupler_ratio", "n_cycles", "period"}
    if scene == "stream":  # §14: the number of cycles and their period (throughput = 3600 / period)
        used |= {"n_cycles", "period"}
    used |= law | {"l"}
    used |= set() if drive == "rigid" else inertia | ({"B2", "K2"} if drive == "flexible" else set())
    used |= {"coupler_ratio"} if vals["profile"] == "crank_rocker" else set()
    used |= {"dt"} if vals["integrator"] == "rk4" else set()
    return used


def same(a: dict, b: dict) -> bool:
    """Equal results, NaN equal to NaN (a stream's: its cycles' table too)."""
    def plain(r):
        return {k: None if isinstance(v, float) and math.isnan(v) else v for k, v in r.items() if k != "cycles"}

    return plain(a) == plain(b) and ("cycles" not in a or a["cycles"].equals(b["cycles"]))


#: draws per scene and parameter: 8, fixed (derandomize), 1,120 in all. 12 before: each draw costs ~7 ms of
#: hypothesis drawing a whole parameter set, whatever the engine does with it, and the four more took ~6 s
#: more CPU of a suite that must finish within 150 s on two cores (README's test command)
EXAMPLES = 8


@pytest.mark.parametrize("name", [n for n in P.NAMES])
@pytest.mark.parametrize("scene", P.SCENES)
@settings(max_examples=EXAMPLES, deadline=None, derandomize=True, database=None,
          suppress_health_check=[HealthCheck.filter_too_much, HealthCheck.too_slow])
@given(data=st.data())
def test_sets_that_differ_in_a_used_parameter_never_share_a_key(scene, name, data):
    given = data.draw(EVERY_PARAMETER, label="given")
    if scene in ("cycle", "stream") and given["integrator"] == "rk4":
        given["t_c"] = given["t_max"] = 1.0  # a fixed step of 1e-4 s over 1 s: 1e4 steps at most
        if given["dt"] is None:  # the derived step, 1e-5 s, is 1e5 steps (~0.1 s a run, most of the file's
            given["dt"] = RANGES["dt"][0]  # time); dt explicit in RANGES' bounds, so that the above holds
    # the second value drawn unequal to the first (a draw of the value alone, not of another whole
    # example that the assume below would reject)
    other = dict(given, **{name: data.draw(value(name).filter(lambda v: v != given[name]), label=f"{name} (other)")})
    try:
        a, b = P.resolve(scene, **given), P.resolve(scene, **other)
    except P.ParameterError:
        assume(False)  # an invalid start or drive: not a parameter set
    assume(a[name] != b[name] or given[name] != other[name])
    ka, kb = P.model_key(a), P.model_key(b)
    if name in uses(scene, a, given) and a[name] != b[name]:
        assert ka != kb, f"{scene}: {name} = {a[name]!r} and {b[name]!r} share a key"
    if ka == kb:  # the engine must then give the same results
        ra, rb = simulate_resolved(a)[0], simulate_resolved(b)[0]
        assert same(ra, rb), f"{scene}: {name} = {a[name]!r} / {b[name]!r} share a key, not the results"


def test_the_keys_the_property_found_merged():
    # a free fall or an impact reads the load's size: the penetration bound of docs/model.md §5
    # failed the 1 cm wide load's free fall that shared the default's key
    for scene in ("freefall", "impact"):
        assert P.model_key(P.resolve(scene)) != P.model_key(P.resolve(scene, A=0.01))
        assert P.model_key(P.resolve(scene)) != P.model_key(P.resolve(scene, L=0.01))
    # a rigid drive's cycle reads I2 (its error control scales the energy integrals by the
    # fence's kinetic energy): results differed by 3e-4 in contact_energy under one key
    rigid = dict(case="small_far", drive="rigid")
    assert P.model_key(P.resolve("cycle", **rigid)) != P.model_key(P.resolve("cycle", **rigid, I2=1.0))
    assert P.model_key(P.resolve("cycle", **rigid, B2=1.0, K2=1.0)) == P.model_key(P.resolve("cycle", **rigid))
