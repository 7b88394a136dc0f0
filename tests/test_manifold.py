"""One overlap, one force (docs/model.md §5.2): the fence meets the load through one manifold.

A corner behind the fence line near the tip and the tip inside the load are two descriptions of
one overlap; the fence pushes with the shallower of the two (the axis of least penetration), never
with both. The geometry here is closed form: the fence at rest along +x (alpha = 0, T = (l, 0)),
the load's lowest corner C = corner 2 a depth D behind the line and x short of the tip, the
load turned by theta, so that its bottom edge rises from C at theta to the fence and its left
edge (x' = -L/2) rises from C at 90 deg - theta. The tip T is inside the load when x < D cot theta,
then D_T = x cos theta + D sin theta below the left edge, and the manifold's depth is
min(D, D_T): one Hertz force k1 m^1.5 at rest, where summing both slots gave k1 (D^1.5 + D_T^1.5).
"""
import math

import numpy as np
import pytest

from fencesweep import resolve
from fencesweep.kernel.jit import python_callable
from fencesweep.kernel.numerics import FACE_TOL
from fencesweep.model.prepare import prepare
from fencesweep.model.scenes.contacts import APART, CLIPPED, FACE, N_SLOTS, PIVOT, PUSH, TIP
from fencesweep.model.scenes.cycle import layout as CL
from fencesweep.model.scenes.cycle import rhs as R
from fencesweep.model.scenes.cycle import slots as S

#: the static tests also run without Numba's JIT (tests/test_plain_python.py); the cycles below do not
plain_python = pytest.mark.plain_python

classify, rhs = python_callable(S.classify), python_callable(R.rhs)
L, A, FL, K1 = 0.7, 0.1, 1.2, 4e6


def fence_force(D, x, theta, L=L, A=A):
    """The load-fence normal force sum [N] of the load at rest with corner 2 at (l - x, -D), turned by
    theta, the fence at rest (rigid drive at t = 0); and the stage."""
    vals = resolve("cycle", L=L, A=A, l=FL, k1=K1, drive="rigid", contact_law="hertz", m1=15.0, R_s=0.0, dP=0.3)
    p = prepare(vals)
    c, s = math.cos(theta), math.sin(theta)
    C = np.array([FL - x, -D])
    X = C - np.array([c * (-L / 2) - s * (-A / 2), s * (-L / 2) + c * (-A / 2)])
    y = np.zeros(CL.N_STATE)
    y[0], y[1], y[2] = X[0], X[1], theta
    iw = np.zeros(CL.N_IW, dtype=np.int64)
    iw[:4] = 1  # every corner on the +n side (5.2)
    iw[CL.IW_MODE] = CL.FM_KINEMATIC
    iw[CL.IW_LOAD] = 1
    codes, tags = np.zeros(N_SLOTS, np.int64), np.zeros(N_SLOTS, np.int64)
    gaps, rates = np.zeros(N_SLOTS), np.zeros(N_SLOTS)
    for _ in range(2):  # enter the codes found, as an event does, and classify again (hysteresis)
        tag = classify(0.0, y, p, iw, codes, gaps, rates, tags)
        iw[CL.IW_CODE:CL.IW_CODE + N_SLOTS] = codes
        iw[CL.IW_EDGE] = tag
    dy, aux = np.zeros(CL.N_STATE), np.zeros(CL.N_AUX_ALL)
    rhs(0.0, y, p, iw, dy, aux)
    pushing = int(np.sum(codes[[0, 1, 2, 3, 8, 9]] != APART))
    return aux[CL.AX_NF], pushing


def _pair_near_the_tip(rng, p):
    """Two states of the load near the fence's tip: iw classified at the first (codes, tag, sides, as
    an event enters them), the second a short move and another velocity away."""
    x, D, theta = rng.uniform(-0.02, 0.05), rng.uniform(-2e-3, 4e-3), rng.uniform(-0.3, 0.6)
    c, s = math.cos(theta), math.sin(theta)
    y0 = np.zeros(CL.N_STATE)
    y0[:2] = np.array([FL - x, -D]) - np.array([c * (-L / 2) - s * (-A / 2), s * (-L / 2) + c * (-A / 2)])
    y0[2] = theta
    y0[3:6] = rng.normal(0.0, 0.5, 3)
    iw = np.zeros(CL.N_IW, dtype=np.int64)
    iw[:4] = 1
    iw[CL.IW_MODE] = CL.FM_KINEMATIC
    iw[CL.IW_LOAD] = 1
    codes, tags = np.zeros(N_SLOTS, np.int64), np.zeros(N_SLOTS, np.int64)
    gaps, rates = np.zeros(N_SLOTS), np.zeros(N_SLOTS)
    for _ in range(2):
        iw[CL.IW_EDGE] = classify(0.0, y0, p, iw, codes, gaps, rates, tags)
        iw[CL.IW_CODE:CL.IW_CODE + N_SLOTS] = codes
        iw[:4] = tags[:4]
    y1 = y0 + np.concatenate([rng.normal(0.0, 1e-3, 2), rng.normal(0.0, 0.02, 1), rng.normal(0.0, 0.3, 3),
                              np.zeros(CL.N_STATE - 6)])
    tag1 = classify(0.0, y1, p, iw, codes, gaps, rates, tags)
    return y1, iw, codes, tags, tag1


@plain_python
def test_the_margins_change_sign_where_the_manifold_changes_a_code():
    """slots.corner_margins and tip_margins, the quantities whose sign change events.known_range
    brackets an event with (docs/model.md §15, Events), are all >= 0 exactly where the manifold
    keeps a corner's code and side (docs/model.md (4.9), (5.2)) or the tip's code (5.7)-(5.9): over
    pairs of states near the tip, the second classified against the first's codes, while the
    manifold's axis stays the face (a corner) or the tip's point stays (the tip)."""
    p = prepare(resolve("cycle", L=L, A=A, l=FL, k1=K1, drive="rigid", contact_law="hertz", m1=15.0, R_s=0.0,
                        dP=0.3))
    frame_at = python_callable(S.frame_at)
    corner_margins, tip_margins = python_callable(S.corner_margins), python_callable(S.tip_margins)
    rng = np.random.default_rng(11)
    seen = set()
    for _ in range(3000):
        y, iw, codes, tags, tag = _pair_near_the_tip(rng, p)
        frame = frame_at(0.0, y, p, iw)
        if tag >= FACE and iw[CL.IW_EDGE] >= FACE:
            for j in range(4):
                keeps = codes[j] == iw[CL.IW_CODE + j] and tags[j] == iw[j]
                assert (min(corner_margins(j, y, p, iw, *frame)) >= 0.0) == keeps, (j, y, iw)
                seen.add(("corner", int(iw[CL.IW_CODE + j]), keeps))
        if iw[CL.IW_CODE + TIP] != APART and tag == iw[CL.IW_EDGE] and codes[PIVOT] == iw[CL.IW_CODE + PIVOT]:
            keeps = codes[TIP] == iw[CL.IW_CODE + TIP]
            assert (min(tip_margins(y, p, iw, *frame)) >= 0.0) == keeps, (y, iw)
            seen.add(("tip on the face" if tag >= FACE else "tip on an edge", int(iw[CL.IW_CODE + TIP]), keeps))
    # each kind of slot, each code, kept and left
    assert {(kind, code, keeps) for kind in ("corner", "tip on the face", "tip on an edge")
            for code in (APART, PUSH, CLIPPED) for keeps in (True, False)
            if not (kind != "corner" and code == APART)} <= seen, seen


@plain_python
def test_a_corner_near_the_tip_and_the_tip_push_once_for_one_overlap():
    # a corner 2 mm deep, 0.3 mm short of the tip, theta 0.3: the two slots gave 357.8 + 357.6 N
    n, pushing = fence_force(2e-3, 0.3e-3, 0.3)
    m = min(2e-3, 0.3e-3 * math.cos(0.3) + 2e-3 * math.sin(0.3))
    assert pushing == 1
    assert n == pytest.approx(K1 * m**1.5, rel=1e-9)
    assert n < K1 * (2e-3) ** 1.5  # not the corner's and the tip's together


@plain_python
@pytest.mark.parametrize("theta", [0.1, 0.3, 0.6, 1.0])
@pytest.mark.parametrize("D", [0.5e-3, 2e-3, 5e-3])
@pytest.mark.parametrize("frac", [0.02, 0.2, 0.5, 0.9, 1.5])
def test_corner_near_the_tip_gives_one_force(theta, D, frac):
    # x as a fraction of D cot(theta), the distance within which the tip is inside the load
    x = frac * D / math.tan(theta)
    n, pushing = fence_force(D, x, theta)
    depth = D if x >= D / math.tan(theta) else min(D, x * math.cos(theta) + D * math.sin(theta))
    assert pushing == 1
    assert n == pytest.approx(K1 * depth**1.5, rel=1e-9)
    assert n <= K1 * D**1.5 * (1 + 1e-12)  # never more than the corner alone


@plain_python
def test_the_force_turns_at_the_tip_without_a_jump():
    # along x through the switch from the corner (D) to the tip (D_T = D): the force is continuous
    D, theta = 2e-3, 0.3
    x_switch = D * (1 - math.sin(theta)) / math.cos(theta)
    xs = x_switch * (1 + np.array([-1e-6, -1e-9, 1e-9, 1e-6]))
    forces = [fence_force(D, x, theta)[0] for x in xs]
    assert max(forces) - min(forces) < 1e-5 * forces[0]


@plain_python
@pytest.mark.parametrize("theta", [0.001, 0.01, 0.1, 0.14, 0.15, 0.3])
def test_a_face_across_the_tip_keeps_its_corner_within_face_tol(theta):
    # the bottom face 1 mm behind the line at its corner 5 mm short of the tip, descending past
    # it by theta: the face (the corner, and U: the tip below that edge, (D + x tan theta) cos
    # theta deep) while the edge lies within acos(1 - FACE_TOL) of the fence, then the tip alone
    # on the edge's axis, as deep (docs/model.md (5.7)); the 1e-10 l bias alone gave the tip
    # alone from 6e-4 rad on
    D, x = 1e-3, 5e-3
    tip = D * math.cos(theta) + x * math.sin(theta)
    n, pushing = fence_force(D, x, -theta)
    if theta < math.acos(1.0 - FACE_TOL):
        assert pushing == 2
        assert n == pytest.approx(K1 * (D**1.5 + tip**1.5), rel=1e-9)
    else:
        assert pushing == 1
        assert n == pytest.approx(K1 * tip**1.5, rel=1e-9)


@plain_python
def test_a_face_flush_in_the_span_pushes_at_both_corners():
    # theta = 0: the bottom face 1 mm behind the line, well inside the span: S3, two corners
    n, pushing = fence_force(1e-3, 0.2, 0.0)
    assert pushing == 2
    assert n == pytest.approx(2 * K1 * (1e-3) ** 1.5, rel=1e-9)


@pytest.mark.parametrize("dP", [0.39, 0.45, 0.51, 0.53])
def test_a_frictionless_elastic_graze_at_the_tip_gives_back_its_energy(dP):
    # small_far past the tip (R_s 0.5), e = 1, no friction at the fence or the belt, a free fence:
    # the kinetic energy of load and fence after the touch is the one before it (docs/model.md
    # §5.2: a change of the manifold inside a contact does no work)
    from fencesweep import simulate_resolved
    vals = resolve("cycle", case="small_far", R_s=0.5, drive="free", mu1=0.0, mu2=0.0, e=1.0, dP=dP)
    r, tr = simulate_resolved(vals, trajectory=True)
    m1, I2 = vals["m1"], vals["m2"] * vals["l"] ** 2 / 3
    I1 = m1 * (vals["L"] ** 2 + vals["A"] ** 2) / 12
    ke = (0.5 * m1 * (tr.vx ** 2 + tr.vy ** 2) + 0.5 * I1 * tr.omega ** 2 + 0.5 * I2 * tr.alpha_dot ** 2).to_numpy()
    touched = np.flatnonzero(tr.N_fence.to_numpy() > 0.0)
    assert r["status"] == "ok" and len(touched) > 0 and r["contact_energy"] == 0.0
    assert tr.N_fence.to_numpy()[-1] == 0.0  # the touch is over
    assert abs(ke[-1] - ke[touched[0] - 1]) <= 1e-3 * ke[touched[0] - 1]


def _hump(cut):
    """The largest peak(dP) / max(peak(dP - 0.02), peak(dP + 0.02)) over a cut {dP: peak}."""
    out = 0.0
    for dP, f in cut.items():
        lo, hi = cut.get(round(dP - 0.02, 4)), cut.get(round(dP + 0.02, 4))
        if lo is None or hi is None or not max(lo, hi) > 0.0:
            continue
        out = max(out, f / max(lo, hi))
    return out


@pytest.mark.parametrize("kw", [
    dict(case="small_far", R_s=0.5, drive="flexible"),   # 2.09 with the double count
    dict(case="small_far", R_s=0.5, drive="free"),       # 1.70
    dict(L=0.7, A=0.1, m1=15.0, R_s=0.3, drive="flexible"),  # a long load: 1.58
    dict(L=0.1, A=0.1, m1=2.0, R_s=0.5, drive="flexible"),   # a short load: 4.10
], ids=["small_far flexible", "small_far free", "long flexible", "short flexible"])
def test_no_hump_across_the_tip_band(kw):
    # dP across the belt through the tip band (docs/model.md §5.2): where a corner and the tip
    # both pushed, the peak force doubled in a narrow band; one manifold leaves no hump
    from fencesweep import simulate
    cut = {}
    for dP in np.round(np.arange(0.05, 0.6001, 0.0025), 4):
        r = simulate("cycle", dP=float(dP), **kw)
        assert r["status"] == "ok"
        cut[float(dP)] = r["peak_force"]
    assert _hump(cut) <= 1.10
