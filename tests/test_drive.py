"""The drive's kinematic constraint (docs/model.md §2)."""
import math

import numpy as np
import pytest

from fencesweep import resolve
from fencesweep.kernel.jit import python_callable
from fencesweep.model import drive as D
from fencesweep.model.drive import crank_rocker_geometry

drive_angle, rocker_angle = python_callable(D.drive_angle), python_callable(D.rocker_angle)
from fencesweep.model.prepare import prepare

pytestmark = pytest.mark.plain_python  # also run without Numba's JIT: tests/test_plain_python.py


def _p(swing, ratio, tc=1.0, profile="crank_rocker"):
    return prepare(resolve("cycle", swing=swing, coupler_ratio=ratio, t_c=tc, profile=profile,
                           R_s=-1.0))


def test_crank_rocker_check_values():
    p = _p(math.pi / 4, 2.5)
    got = [math.degrees(drive_angle(f, p)[0]) for f in (1 / 6, 1 / 3, 2 / 3, 5 / 6)]
    assert got == pytest.approx([12.328, 34.430, 35.258, 13.293], abs=1e-3)


@pytest.mark.parametrize("swing, ratio", [(0.7330, 2.5), (0.5, 1.2), (1.2, 4.0)])
def test_crank_rocker_swings_exactly_psi_with_time_ratio_one(swing, ratio):
    tc = 1.7
    p = _p(swing, ratio, tc)
    assert drive_angle(0.5 * tc, p)[0] == pytest.approx(swing, abs=1e-10)
    assert abs(drive_angle(0.5 * tc, p)[1]) < 1e-7
    ts = np.linspace(1e-6, tc - 1e-6, 2001)
    a = np.array([drive_angle(t, p)[0] for t in ts])
    assert a.min() >= -1e-10 and a.max() <= swing + 1e-10
    assert drive_angle(1e-9, p)[0] == pytest.approx(0.0, abs=1e-12)
    assert drive_angle(tc - 1e-9, p)[0] == pytest.approx(0.0, abs=1e-12)


def test_drive_rate_is_the_derivative_of_the_angle():
    for profile in ("crank_rocker", "harmonic"):
        p = _p(0.733, 2.5, 1.36, profile)
        for t in np.linspace(0.05, 1.3, 17):
            h = 1e-6
            num = (drive_angle(t + h, p)[0] - drive_angle(t - h, p)[0]) / (2 * h)
            assert drive_angle(t, p)[1] == pytest.approx(num, rel=1e-6, abs=1e-8)


def test_drive_rests_outside_the_cycle():
    p = _p(0.733, 2.5, 1.36)
    for t in (-1.0, 0.0, 1.36, 2.0):
        assert drive_angle(t, p) == (0.0, 0.0)


def test_harmonic_profile_closed_form():
    p = _p(0.6, 2.5, 2.0, "harmonic")
    for t in np.linspace(0.01, 1.99, 9):
        assert drive_angle(t, p)[0] == pytest.approx(0.3 * (1 - math.cos(math.pi * t)), abs=1e-14)


def test_rocker_pin_is_on_both_circles_and_left_of_the_line():
    a, b, d, th0, _ = crank_rocker_geometry(0.733, 2.5)
    for th in np.linspace(0, 2 * math.pi, 13):
        beta, _ = rocker_angle(th, a, b, d)
        bx, by = d + math.cos(beta), math.sin(beta)
        ax, ay = a * math.cos(th), a * math.sin(th)
        assert math.hypot(bx - ax, by - ay) == pytest.approx(b, abs=1e-12)
        # left of the directed line from A to (d, 0): positive cross product
        assert (d - ax) * (by - ay) - (0 - ay) * (bx - ax) > 0


def test_drive_table_matches_the_exact_four_bar():
    # the kernel interpolates a table of beta(theta); compare with the closed-form linkage
    for swing, ratio, tc in [(0.733, 2.5, 1.36), (1.2, 1.3, 0.9)]:
        p = _p(swing, ratio, tc)
        a, b, d, th0, b0 = crank_rocker_geometry(swing, ratio)
        for t in np.random.default_rng(3).uniform(0, tc, 500):
            beta, dbeta = rocker_angle(th0 + 2 * math.pi * t / tc, a, b, d)
            aw, daw = drive_angle(t, p)
            assert aw == pytest.approx(math.remainder(beta - b0, 2 * math.pi), abs=1e-10)
            assert daw == pytest.approx(dbeta * 2 * math.pi / tc, abs=1e-8)
