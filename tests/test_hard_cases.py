"""Hard cases: stiff and soft contacts, grazing and repeated impacts, stick-slip
friction, tiny and heavy loads, extreme drives. Each must give finite results with status ok,
no tunnelling (penetration far below the failure bound) and results that converge as the
step shrinks: the default step and a 4x finer one agree in outcome and to 1e-3."""
import math

import pytest

from fencesweep import resolve, simulate, simulate_resolved

#: also run without Numba's JIT (tests/test_plain_python.py), except JIT_ONLY
plain_python = pytest.mark.plain_python

I2 = 5.0 * 1.2**2 / 3


def _k2_for_psi(psi, B2=72.0):
    """K2 giving relative damping Psi = B2 / (2 sqrt(K2 I2)) (docs/model.md §3)."""
    return (B2 / (2 * psi)) ** 2 / I2


HARD = {
    "k1=1e9": dict(case="small_far", k1=1e9),
    "k1=1e5": dict(case="small_far", k1=1e5),
    "k1=1e9 long_near": dict(case="long_near", k1=1e9),
    "k1=1e5 long_near": dict(case="long_near", k1=1e5),
    "eps_v=1e-5": dict(case="small_far", eps_v=1e-5),
    "eps_v=1e-5 long_near": dict(case="long_near", eps_v=1e-5),
    "m1=0.1": dict(case="small_far", m1=0.1),
    "m1=100": dict(case="small_far", m1=100.0),
    "m1=0.1 long_near": dict(case="long_near", m1=0.1),
    "m1=100 long_near": dict(case="long_near", m1=100.0),
    "free fence": dict(case="small_far", drive="free"),
    "rigid fence": dict(case="long_near", drive="rigid"),
    "Psi=5": dict(case="small_far", K2=_k2_for_psi(5.0)),
    "Psi=0.05": dict(case="small_far", K2=_k2_for_psi(0.05)),
    "K2=0, B2=72": dict(case="small_far", K2=0.0),
    "v=0.1": dict(case="small_far", v=0.1),
    "v=5": dict(case="long_near", v=5.0),
    "phi0=+pi/4": dict(L=0.3, A=0.2, phi0=math.pi / 4, dP=0.2),
    "phi0=-pi/4": dict(L=0.3, A=0.2, phi0=-math.pi / 4, dP=0.2),
    "jammed at the pivot, mu2=1": dict(case="long_near", mu2=1.0),
    "face flush along the fence": dict(L=0.6, A=0.15, dP=0.3, R_s=-0.2),
    "hit by the tip": dict(L=0.3, A=0.3, dP=0.4, R_s=0.3),
    "thrown back and returns": dict(L=0.2, A=0.1, dP=0.55, R_s=-0.6, B2=10.0, K2=2000.0),
}


#: the long_near twins of small_far cases: the same contact code, and without the JIT the slowest
#: (2-6 s each, 2-3x that under the plain run's coverage); they run compiled only
JIT_ONLY = {"k1=1e9 long_near", "k1=1e5 long_near", "eps_v=1e-5 long_near", "m1=0.1 long_near", "m1=100 long_near"}


@pytest.mark.parametrize("name", [pytest.param(n, marks=() if n in JIT_ONLY else plain_python) for n in HARD])
def test_hard_case_is_stable_and_converges(name):
    kw = HARD[name]
    a = simulate(**kw)
    b = simulate(**kw, step_factor=0.25)
    for r in (a, b):
        assert r["status"] == "ok", r["status"]
        assert all(math.isfinite(r[k]) for k in ("t_exit", "peak_force", "deflection_max", "alpha_max",
                                                  "damper_energy", "contact_energy", "x_exit"))
    vals = resolve("cycle", kw.get("case"), **{k: v for k, v in kw.items() if k != "case"})
    # no tunnelling: far below the failure bound of docs/model.md §5 (half the smaller side); the
    # soft contact k1 = 1e5 puts the tip 1.09 cm below the edge it pushes (§5.2)
    assert a["max_penetration"] < 0.25 * min(vals["L"], vals["A"])
    assert a["outcome"] == b["outcome"]
    for key in ("peak_force", "deflection_max"):
        assert a[key] == pytest.approx(b[key], rel=1e-3, abs=1e-6 * a["freefall_force"])
    assert a["t_exit"] == pytest.approx(b["t_exit"], rel=1e-3)


@plain_python
def test_hard_cases_exercise_what_they_claim(tip_depth):
    jam = simulate(**HARD["jammed at the pivot, mu2=1"])
    assert jam["t_S4"] > 0.3  # fence and rail together
    flush = simulate(**HARD["face flush along the fence"])
    assert flush["t_S3"] > 0.15  # two corners on the fence
    back = simulate(**HARD["thrown back and returns"])
    assert back["n_impacts"] >= 2  # separated and hit again
    free = simulate(**HARD["K2=0, B2=72"])
    assert free["residual_deflection"] > 0.01  # no spring to bring the fence home
    vals = resolve("cycle", **HARD["hit by the tip"])
    _, tr = simulate_resolved(vals, trajectory=True)
    touching = tr[tr.N_fence > 100]
    assert any(tip_depth(row, vals) > 0 for row in touching.itertuples())


def _grazing_start():
    """The R_s at which small_far goes from missing the fence to touching it (bisection)."""
    lo, hi = -1.2, -0.9
    assert simulate(case="small_far", R_s=lo)["n_impacts"] == 0
    assert simulate(case="small_far", R_s=hi)["n_impacts"] > 0
    for _ in range(30):
        mid = 0.5 * (lo + hi)
        if simulate(case="small_far", R_s=mid)["n_impacts"] > 0:
            hi = mid
        else:
            lo = mid
    return hi


@plain_python
def test_grazing_impact_is_not_missed_by_coarse_steps():
    # a corner that barely touches the fence: the default step must see the same contact
    # as a 16x finer step (no tunnelling through a sub-millisecond touch)
    rs = _grazing_start() + 1e-6
    rows = [simulate(case="small_far", R_s=rs, step_factor=sf) for sf in (1.0, 0.25, 0.0625)]
    for r in rows:
        assert r["status"] == "ok" and r["n_impacts"] == 1
        assert 0 < r["max_penetration"] < 1e-5 and r["peak_force"] < 100.0
    assert len({r["outcome"] for r in rows}) == 1
    f = [r["peak_force"] for r in rows]
    assert abs(f[0] - f[2]) < 1.0 and abs(f[1] - f[2]) <= abs(f[0] - f[2]) + 1e-9
