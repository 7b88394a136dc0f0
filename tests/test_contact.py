"""Contact laws and their calibration (docs/model.md §4, §6, §7) against closed forms and the values
that docs/model.md states."""
import math

import numpy as np
import pytest
from scipy.integrate import dblquad

from fencesweep import simulate
from fencesweep.model.calibrate import damping_coefficient
from fencesweep.kernel.jit import python_callable
from fencesweep.model import contact as C
from fencesweep.model.contact import drop_speed, hertz_contact_time, hertz_peak, mean_footprint_radius

# the compiled formulas, called from Python through a callable copy (kernel/jit.py)
belt_friction, coulomb, normal_force = (python_callable(f) for f in (C.belt_friction, C.coulomb, C.normal_force))

pytestmark = pytest.mark.plain_python  # also run without Numba's JIT: tests/test_plain_python.py


@pytest.mark.parametrize("e, q", [(0.2, 1.6351), (0.5, 0.5708), (0.9, 0.0766)])
def test_q_of_e_matches_model_reference_values(e, q):
    assert damping_coefficient(e, "hertz") == pytest.approx(q, abs=2e-4)


def test_linear_damping_matches_damped_oscillator_closed_form():
    # x'' + beta x' + x = 0 from x = 0, x' = 1 (underdamped): x = exp(-zeta t) sin(wd t)/wd,
    # zeta = beta/2, wd = sqrt(1 - zeta^2); the clipped force x + beta x' first returns to 0
    # at t_sep, and the rebound speed there must be e.
    beta = damping_coefficient(0.5, "linear")
    zeta = beta / 2
    wd = math.sqrt(1 - zeta**2)
    # x(t) = exp(-zeta t) sin(wd t)/wd; force x + beta x' = 0 at the first t > 0
    f = lambda t: math.exp(-zeta * t) * (math.sin(wd * t) / wd * (1 - beta * zeta) + beta * math.cos(wd * t))
    from scipy.optimize import brentq
    t_sep = brentq(f, 1e-9, math.pi / wd, xtol=1e-15)
    v_sep = math.exp(-zeta * t_sep) * (math.cos(wd * t_sep) - zeta * math.sin(wd * t_sep) / wd)
    assert -v_sep == pytest.approx(0.5, abs=1e-7)  # calibrated by the compiled RK4 impact kernel


def test_normal_force_is_clipped_and_starts_from_zero():
    n, n_el = normal_force(0.0, 3.0, 4e6, 1e4, 0)
    assert n == 0.0  # modified Kelvin starts from 0 at contact (paper Fig. 3)
    n, n_el = normal_force(0.0, 3.0, 4e6, 1e4, 1)
    assert n == pytest.approx(3e4)  # linear law jumps (paper Fig. 2)
    n, n_el = normal_force(1e-3, -50.0, 4e6, 1e4, 0)
    assert n == 0.0 and n_el > 0  # no adhesion


def test_freefall_peak_matches_model_value():
    r = simulate("freefall")
    assert r["peak_force"] == pytest.approx(6414.0, abs=1.0)  # docs/model.md §7: 6.414 kN


def test_freefall_without_damping_matches_hertz_closed_form():
    r = simulate("freefall", e=1.0)
    vh = drop_speed(0.3)
    assert r["peak_force"] == pytest.approx(hertz_peak(15.0, 4e6, vh), rel=1e-6)
    assert r["peak_force"] == pytest.approx(7354.0, abs=1.0)
    assert r["contact_time"] == pytest.approx(hertz_contact_time(15.0, 4e6, vh), rel=1e-4)
    assert r["e_eff"] == pytest.approx(1.0, abs=1e-6)


@pytest.mark.parametrize("e", [0.2, 0.5, 0.9])
@pytest.mark.parametrize("law", ["hertz", "linear"])
def test_rigid_wall_impulse_and_restitution(e, law):
    m1, w = 7.0, 1.3
    r = simulate("impact", drive="rigid", e=e, m1=m1, w=w, contact_law=law)
    assert r["impulse"] == pytest.approx(m1 * w * (1 + e), rel=1e-6)  # docs/model.md §7
    assert r["e_eff"] == pytest.approx(e, abs=1e-6)


def test_restitution_is_independent_of_speed_and_stiffness():
    a = simulate("impact", drive="rigid", w=0.3, k1=1e5)
    b = simulate("impact", drive="rigid", w=5.0, k1=1e9, m1=2.0)
    assert a["e_eff"] == pytest.approx(0.2, abs=1e-6)
    assert b["e_eff"] == pytest.approx(0.2, abs=1e-6)


def test_mean_footprint_radius_against_quadrature():
    for L, A in [(1.0, 1.0), (0.7, 0.1), (0.2, 0.1), (0.8, 0.4)]:
        num, _ = dblquad(lambda y, x: math.hypot(x, y), -L / 2, L / 2, -A / 2, A / 2, epsabs=1e-12)
        assert mean_footprint_radius(L, A) == pytest.approx(num / (L * A), rel=1e-9)
    assert mean_footprint_radius(1.0, 1.0) == pytest.approx(0.38260, abs=1e-5)


def test_friction_never_exceeds_its_limit():
    rng = np.random.default_rng(1)
    for _ in range(2000):
        N = rng.uniform(0, 1e4)
        w = rng.normal() * 10 ** rng.uniform(-8, 1)
        mu = rng.uniform(0, 1)
        eps = 10 ** rng.uniform(-6, -1)
        f = coulomb(N, w, mu, eps)
        assert abs(f) <= mu * N * (1 + 1e-12)
        assert f * w <= 0.0  # opposes the slip
        ux, uy, om = rng.normal(size=3) * 10 ** rng.uniform(-6, 1, size=3)
        fmax, mmax = rng.uniform(0.1, 100), rng.uniform(0.01, 10)
        fx, fy, m = belt_friction(ux, uy, om, fmax, mmax, mmax / fmax, eps)
        # the force-moment pair stays inside the limit ellipse (Goyal-Ruina, docs/model.md §6)
        assert (fx * fx + fy * fy) / fmax**2 + (m / mmax) ** 2 <= 1 + 1e-12
        assert fx * ux + fy * uy + m * om <= 1e-12  # dissipative


def test_linear_law_freefall_peak_is_the_jump_when_overdamped():
    # x'' = -(x + beta x'): the force starts at beta (times w sqrt(m1 k_lin)) and its rate
    # w k (1 - beta^2) is negative for beta > 1, so the peak is the jump at contact, b_lin v_H
    from fencesweep.model.contact import derived_k_lin
    beta = damping_coefficient(0.2, "linear")
    assert beta > 1
    k_lin = derived_k_lin(15.0, 4e6, 0.3)
    expect = beta * math.sqrt(15.0 * k_lin) * drop_speed(0.3)
    assert simulate("freefall", contact_law="linear")["peak_force"] == pytest.approx(expect, rel=1e-9)


@pytest.mark.parametrize("law", ["hertz", "linear"])
@pytest.mark.parametrize("e, m1, H", [(0.2, 15.0, 0.3), (0.05, 2.0, 1.0), (0.9, 40.0, 0.1), (1.0, 15.0, 0.3)])
def test_freefall_force_from_the_dimensionless_peak_matches_the_freefall_scene(law, e, m1, H):
    """docs/model.md (7.7): the overload's reference, a force scale times n(e) solved once per
    (e, law) with SciPy, equals the freefall scene's own integration of (7.2) with the engine."""
    from fencesweep.model.prepare import freefall_force

    scene = simulate("freefall", e=e, m1=m1, H=H, contact_law=law)["peak_force"]
    assert freefall_force(m1, 4e6, e, law, None, H) == pytest.approx(scene, rel=1e-8)


def test_undamped_freefall_force_is_the_hertz_closed_form():
    from fencesweep.model.prepare import freefall_force

    assert freefall_force(15.0, 4e6, 1.0, "hertz", None, 0.3) == pytest.approx(
        hertz_peak(15.0, 4e6, drop_speed(0.3)), rel=1e-9)  # (7.4)


@pytest.mark.parametrize("law", [0, 1])
def test_code_margins_change_sign_exactly_where_the_slots_code_changes(law):
    """contacts.code_margins are all >= 0 exactly when next_code keeps the code (docs/model.md
    (4.9)), for every code, over penetrations and rates on both sides of each threshold: the signs
    that events.known_range brackets a contact change with."""
    from fencesweep.model.scenes import contacts as K

    next_code, code_margins = python_callable(K.next_code), python_callable(K.code_margins)
    kc, cd, d_gap, d_force = 4e6, 2.0e3, 1e-6, 1e-3
    rng = np.random.default_rng(7)
    D = np.concatenate([rng.normal(0.0, 1e-3, 300), rng.normal(0.0, 2e-6, 300), [0.0, -d_gap, -2 * d_gap]])
    Dd = np.concatenate([rng.normal(0.0, 0.5, 300), rng.normal(0.0, 1e-3, 300), [0.0, 0.0, 1.0]])
    seen = set()
    for cur in (K.APART, K.PUSH, K.CLIPPED):
        for d, dd in zip(D, Dd):
            keeps = next_code(cur, d, dd, True, kc, cd, law, d_gap, d_force) == cur
            assert (min(code_margins(cur, d, dd, kc, cd, law, d_gap, d_force)) >= 0.0) == keeps, (cur, d, dd)
            seen.add((cur, keeps))
    assert len(seen) == 6  # every code both kept and left
