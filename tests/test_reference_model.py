"""Fast sanity tests of the independent reference model (tests/reference/model.py).

They check the reference against the closed forms and stated numbers of docs/model.md, so
that it can be trusted as the yardstick of the engine.  Total run time a few s.
"""

import math

import pytest
from reference import model as ref  # tests/reference/model.py (pyproject's pytest pythonpath)

G = 9.81


# --- §4 contact law calibration ---------------------------------------------------

@pytest.mark.parametrize("e, q", [(0.2, 1.6351), (0.5, 0.5708), (0.9, 0.0766)])
def test_q_of_e_reference_values(e, q):
    assert abs(ref.q_from_e(e) - q) <= 2e-4


def test_q_calibration_is_consistent():
    # the rebound of the calibrated law is e to high accuracy; e = 1 is q = 0
    for e in (0.1, 0.2, 0.7):
        assert abs(ref._rebound_hertz(ref.q_from_e(e)) - e) < 1e-9
        assert abs(ref._rebound_linear(ref.zeta_from_e(e)) - e) < 1e-9
    assert ref.q_from_e(1.0) == 0.0


# --- §7 free fall -------------------------------------------------------------------

def test_freefall_peak_and_impulse():
    r = ref.simulate_reference({}, scene="freefall")
    assert r["status"] == "ok"
    assert abs(r["peak_force"] - 6414.0) < 1.0            # docs/model.md §4, §7: 6.414 kN
    vH = math.sqrt(2 * G * 0.3)
    assert r["impulse"] == pytest.approx(15.0 * vH * 1.2, rel=1e-8)   # m1 w (1 + e)
    assert r["e_eff"] == pytest.approx(0.2, abs=1e-8)


def test_hertz_closed_form_with_e_equal_1():
    m1, k1 = 15.0, 4.0e6
    vH = math.sqrt(2 * G * 0.3)
    r = ref.simulate_reference({"e": 1.0}, scene="freefall")
    F0 = k1 * (5 * m1 * vH ** 2 / (4 * k1)) ** 0.6
    assert F0 == pytest.approx(7354.0, abs=1.0)
    assert r["peak_force"] == pytest.approx(F0, rel=1e-8)
    assert r["contact_time"] == pytest.approx(3.2181 * (m1 ** 2 / (k1 ** 2 * vH)) ** 0.2,
                                              rel=5e-5)
    assert r["e_eff"] == pytest.approx(1.0, abs=1e-8)


def test_default_k_lin_matches_undamped_hertz_peak():
    # linear law, e = 1: the free-fall peak is sqrt(k_lin m1) v_H = F0 (§4)
    r_lin = ref.simulate_reference({"e": 1.0, "contact_law": "linear"}, scene="freefall")
    r_her = ref.simulate_reference({"e": 1.0}, scene="freefall")
    assert r_lin["peak_force"] == pytest.approx(r_her["peak_force"], rel=1e-8)


# --- §2 drive ---------------------------------------------------------------------------

def test_crank_rocker_check_values():
    d = ref.Drive("crank_rocker", math.pi / 4, 1.0, 2.5)
    got = [math.degrees(d(f)[0]) for f in (1 / 6, 1 / 3, 2 / 3, 5 / 6)]
    for g, want in zip(got, (12.328, 34.430, 35.258, 13.293)):
        assert abs(g - want) < 1e-3
    assert abs(d(0.0)[0]) < 1e-14 and abs(d(0.0)[1]) < 1e-9
    assert d(0.5)[0] == pytest.approx(math.pi / 4, abs=1e-12)
    assert abs(d(1.0)[0]) < 1e-12
    h = 1e-6                                   # rate = derivative of the angle
    for t in (0.1, 0.37, 0.8):
        fd = (d(t + h)[0] - d(t - h)[0]) / (2 * h)
        assert d(t)[1] == pytest.approx(fd, rel=1e-7)


def test_drive_rests_outside_cycle():
    d = ref.Drive("harmonic", 0.733, 1.36, 2.5)
    assert d.at(-0.1) == (0.0, 0.0) and d.at(1.5) == (0.0, 0.0)
    assert d.at(0.68)[0] == pytest.approx(0.733, rel=1e-14)


# --- §6 footprint -----------------------------------------------------------------------

def test_rho_bar_unit_square():
    assert ref.rho_bar(1.0, 1.0) == pytest.approx(0.38260, abs=5e-6)


# --- §8 impact: the paper's Fig. 5b ratio (docs/model.md §13.3) --------------------------------

def test_impact_rigid_over_free_peak_ratio():
    rigid = ref.simulate_reference({"drive": "rigid"}, scene="impact")
    free = ref.simulate_reference({"drive": "free", "m2": 5.0}, scene="impact")
    assert rigid["peak_force"] / free["peak_force"] == pytest.approx(1.74, abs=0.01)
    # free fence: momentum shared, so the impulse is below m1 w (1 + e)
    assert free["impulse"] < 15.0 * 2.0 * 1.2


# --- §1 input checks --------------------------------------------------------------------

def test_invalid_starts_name_the_parameter():
    with pytest.raises(ValueError, match="R_s"):
        ref.simulate_reference({"R_s": 1.2})
    with pytest.raises(ValueError, match="dP"):
        ref.simulate_reference({"case": "small_far", "dP": 0.65})
    with pytest.raises(ValueError, match="nonsense"):
        ref.simulate_reference({"nonsense": 1.0})


# --- cycle ------------------------------------------------------------------------------

def test_free_ride_escape_time_closed_form():
    # no contact (load passes before the fence rises): it rides with the belt and
    # escapes when its rear corner passes x = l: t = (l - (R_s - L)) / v
    r = ref.simulate_reference({"case": "small_far", "v": 3.0, "drive": "rigid"}, rtol=1e-8)
    assert r["outcome"] == "escaped" and r["n_impacts"] == 0
    assert r["t_exit"] == pytest.approx((1.2 + 0.2) / 3.0, rel=1e-10)
    assert r["peak_force"] == 0.0 and r["contact_energy"] == 0.0


def test_small_far_rigid_overload_042():
    # docs/model.md §12: rigid fence, swing 42 deg, small_far: overload 0.97
    r = ref.simulate_reference({"case": "small_far", "drive": "rigid"}, rtol=1e-8)
    assert r["outcome"] == "scraped"
    assert r["overload"] == pytest.approx(0.97, abs=0.005)
    assert r["deflection_max"] == 0.0 and r["damper_energy"] == 0.0
    assert r["alpha_max"] == pytest.approx(math.radians(42.0), abs=1e-9)   # swing exactly


def test_paper_flexible_fence_contacts_longer_and_carries_further():
    # docs/model.md §13.6 for both unfavourable loads
    for case in ("small_far", "long_near"):
        flex = ref.simulate_reference({"case": case}, rtol=1e-7)
        rig = ref.simulate_reference({"case": case, "drive": "rigid"}, rtol=1e-7)
        assert flex["outcome"] == rig["outcome"] == "scraped"
        assert flex["contact_time"] > rig["contact_time"]
        assert flex["x_exit"] > rig["x_exit"]
        assert 0.0 < flex["deflection_max"] < 0.2618
        assert flex["peak_force"] < rig["peak_force"]


def test_cycle_converges_with_tolerance_and_methods():
    a = ref.simulate_reference({"case": "small_far"}, rtol=1e-6)
    b = ref.simulate_reference({"case": "small_far"}, rtol=1e-9)
    assert a["peak_force"] == pytest.approx(b["peak_force"], rel=1e-5)
    assert a["t_exit"] == pytest.approx(b["t_exit"], rel=1e-6)
    assert a["contact_energy"] == pytest.approx(b["contact_energy"], rel=1e-4)
    for m in ("RK45", "LSODA", "Radau"):
        c = ref.simulate_reference({"case": "small_far"}, rtol=1e-6, method=m)
        assert c["status"] == "ok"
        assert c["peak_force"] == pytest.approx(b["peak_force"], rel=1e-4)


def test_friction_regularisation_converges():
    a = ref.simulate_reference({"case": "small_far", "eps_v": 1e-3}, rtol=1e-8)
    b = ref.simulate_reference({"case": "small_far", "eps_v": 1e-5}, rtol=1e-8)
    assert a["peak_force"] == pytest.approx(b["peak_force"], rel=1e-3)
    assert a["t_exit"] == pytest.approx(b["t_exit"], rel=1e-3)


def _mechanical_energy(model, mode, y, t):
    """Kinetic + fence spring + contact elastic energy [J] (no dissipation terms)."""
    x, yc, ph, u, w, om = y[:6]
    E = 0.5 * model.m1 * (u * u + w * w) + 0.5 * model.I1 * om * om
    al, ald, aw, awd = model.fence(t, y, mode)
    E += 0.5 * model.I2 * ald ** 2 + 0.5 * mode.K2 * (aw - al) ** 2
    engaged = mode.engaged()           # the points of the manifold's axis in use (§5.2)
    engaged += [("rl", j) for j in range(4) if mode.rl_region[j] and mode.rl_state[j]]
    for kind, j in engaged:
        D = max(model.contact_now(t, y, mode, kind, j)[0], 0.0)
        E += 0.4 * model.law.k * D ** 2.5
    return E


@pytest.mark.parametrize("geom, kind", [
    ({"case": "small_far"}, "cf"),
    ({"L": 0.4, "A": 0.1, "dP": 0.55, "R_s": 0.3}, "tip"),
    ({"L": 0.3, "A": 0.1, "dP": 0.001, "R_s": -0.05}, "rail"),
])
def test_energy_conserved_free_fence_frictionless_elastic(geom, kind):
    # after its release the free fence, the load and the elastic (e = 1) frictionless
    # contacts form a conservative system: a wrong sign of a force, a moment or D'
    # shows up as an energy drift
    p = ref.resolve_params({**geom, "drive": "free", "mu1": 0.0, "mu2": 0.0, "e": 1.0})
    res, _ = ref.simulate_cycle(p, rtol=1e-9, keep_trajectory=True)
    model = res["_model"]
    energies, kinds = [], set()
    for (t0, t1, md, sol, _) in res["_segments"]:
        if md.fence_dyn and t1 > t0:
            energies += [_mechanical_energy(model, md, sol(t0), t0),
                         _mechanical_energy(model, md, sol(t1), t1)]
            if md.n_fence_active():    # the fence's face (corners, U) or a load edge (the tip)
                kinds |= {"cf" if md.axis == ref.AXIS_F else "tip"}
            kinds |= {"rail" for j in range(4) if md.rl_region[j] and md.rl_state[j]}
    assert kind in kinds
    assert max(energies) - min(energies) < 1e-6 * energies[0]


def test_contact_energy_is_the_mechanical_energy_lost():
    # free fence, no friction, e = 0.2: what the system loses after the release is
    # exactly the contact_energy (damping part + the clipped phase)
    p = ref.resolve_params({"case": "small_far", "drive": "free", "mu1": 0.0, "mu2": 0.0})
    res, _ = ref.simulate_cycle(p, rtol=1e-9, keep_trajectory=True)
    model = res["_model"]
    segs = [s for s in res["_segments"] if s[2].fence_dyn and s[1] > s[0]]
    (t0, _, m0, sol0, _), (_, t1, m1, sol1, _) = segs[0], segs[-1]
    lost = _mechanical_energy(model, m0, sol0(t0), t0) - _mechanical_energy(model, m1, sol1(t1), t1)
    assert res["contact_energy"] > 1.0
    assert lost == pytest.approx(res["contact_energy"], rel=1e-6)


def test_contact_diagnostics_per_kind():
    # free ride (no contact): the load keeps y, so its rail gap is dP exactly; nothing
    # touches and the closest approaches are positive
    r = ref.simulate_reference({"case": "small_far", "v": 3.0, "drive": "rigid"}, rtol=1e-8)
    assert not (r["touch_fence"] or r["touch_tip"] or r["touch_rail"])
    assert r["max_pen_fence"] == r["max_pen_tip"] == r["max_pen_rail"] == 0.0
    assert r["min_gap_rail"] == pytest.approx(0.6, abs=1e-12)
    assert r["min_gap_fence"] > 0.0 and r["min_gap_tip"] > 0.0
    # long_near touches the fence and the rail.  Sliding on past the tip, the load flush on
    # the fence covers the tip (0.24 mm deep), and one manifold pushes there (§5.2): the
    # fence's face while a corner of it touches, the load's edge once U is the face's only
    # point.  The deepest contact is max_penetration
    r = ref.simulate_reference({"case": "long_near"}, rtol=1e-8)
    assert r["touch_fence"] and r["touch_rail"]
    assert r["min_gap_fence"] == r["min_gap_tip"] == r["min_gap_rail"] == 0.0
    deepest = max(r["max_pen_fence"], r["max_pen_tip"], r["max_pen_rail"])
    assert deepest == pytest.approx(r["max_penetration"], rel=1e-9)
    assert r["max_pen_rail"] > 1e-4 and r["max_pen_tip"] > 1e-4
    # small_far: the rising tip pushes into the load's bottom edge (a load edge's axis)
    r = ref.simulate_reference({"case": "small_far"}, rtol=1e-8)
    assert r["touch_fence"] and r["touch_tip"] and not r["touch_rail"]
    assert r["max_pen_tip"] > 5e-4


# --- §5.2 one manifold: the fence and the load push once -------------------------------

def _overlap_near_tip(model, theta, depth, short, past_edge):
    """The load at rest, fence at alpha = 0 (s = x, h = y): its corner C lies `depth` behind
    the fence line and `short` short of the tip, and its edge C -> C' runs past the tip
    at theta to the fence, rising (C' in front of the line).  past_edge "long": that edge
    is the L edge, "short": the A edge.  The full state (rigid drive)."""
    l = model.l
    Cx, Cy = l - short, -depth
    if past_edge == "long":      # x' along the edge: C is corner 2 (-L/2, -A/2)
        phi, j = theta, 2
    else:                        # y' along the edge: C is corner 3 (+L/2, -A/2)
        phi, j = theta - math.pi / 2, 3
    c, s = math.cos(phi), math.sin(phi)
    ox, oy = model.cx[j], model.cy[j]
    return [Cx - (c * ox - s * oy), Cy - (s * ox + c * oy), phi, 0.0, 0.0, 0.0, 0.0, 0.0], j


@pytest.mark.parametrize("past_edge", ["long", "short"])
@pytest.mark.parametrize("theta", [0.2, 0.3, 0.45])
@pytest.mark.parametrize("depth", [1e-3, 2e-3, 3e-3])
@pytest.mark.parametrize("short", [1e-4, 3e-4, 6e-4])
def test_corner_and_tip_in_one_overlap_push_once(past_edge, theta, depth, short):
    """docs/model.md §5.2: a corner 2 mm behind the fence line and 0.3 mm short of the tip,
    its edge at 0.3 rad to the fence, also has the tip inside the load.  The old rule
    summed the corner-fence and the tip-edge forces; one manifold gives a single force:
    that of the axis of least penetration (5.7), here the tip on the load's edge at C
    across the one that runs past the tip (the fence enters the load through that edge),
    at depth short cos(theta) + depth sin(theta): less than the corner's."""
    p = ref.resolve_params({"contact_law": "hertz", "k1": 4.0e6, "L": 0.7, "A": 0.1,
                            "l": 1.2, "drive": "rigid"})
    model = ref.CycleModel(p)
    y, jc = _overlap_near_tip(model, theta, depth, short, past_edge)
    mode = model.mode_at(0.0, y, drive="rigid", drive_on=False)
    # both descriptions of the overlap are there: the corner behind the line, T inside
    assert mode.touch and mode.tip_inside
    assert model.contact_now(0.0, y, mode, "cf", jc)[0] == pytest.approx(depth, rel=1e-9)
    Nf = model.evaluate(0.0, y, mode, want_rhs=False)[1][0]
    pushing = [q for q in mode.axis_points() if mode.state(*q) == ref.ACTIVE]
    assert len(pushing) == 1 and mode.n_fence_active() == 1 and mode.stage() == "S1"
    D, Dd, N = model.contact_now(0.0, y, mode, *pushing[0])
    assert Dd == 0.0 and Nf == pytest.approx(4.0e6 * D ** 1.5, rel=1e-12) == N
    # the axis of least penetration; the corner's own force is not added
    sn = ref._Snap(model, 0.0, y, mode)
    ms = [model.measure(sn, mode, X) for X in ref.AXIS_ORDER]
    assert D == pytest.approx(min(ms), rel=1e-12)
    tip_depth = short * math.cos(theta) + depth * math.sin(theta)
    assert mode.axis != ref.AXIS_F and pushing[0][0] == "ep" and pushing[0][1] % 2 == 1
    assert D == pytest.approx(tip_depth, rel=1e-9) and D < depth
    corner_plus_tip = 4.0e6 * depth ** 1.5 + 4.0e6 * tip_depth ** 1.5
    assert Nf < 4.0e6 * depth ** 1.5 < corner_plus_tip


# --- independence ------------------------------------------------------------------------

def test_the_reference_imports_nothing_of_the_engine():
    """The model, its data's reader and its tools share no code with the engine (only compare.py,
    the judge, applies the package's agreement metric): read with `ast`, nothing imported."""
    import ast
    from pathlib import Path

    import reference

    for name in ("__init__.py", "model.py", "make.py", "find_grazes.py"):
        tree = ast.parse((Path(reference.__file__).parent / name).read_text())
        imported = {a.name for n in ast.walk(tree) if isinstance(n, ast.Import) for a in n.names}
        imported |= {n.module or "" for n in ast.walk(tree) if isinstance(n, ast.ImportFrom)}
        assert not {m for m in imported if m.split(".")[0] == "fencesweep"}, name
