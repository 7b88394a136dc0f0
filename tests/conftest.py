"""Helpers shared by the test files, as fixtures (a test file never imports another).

tests/ is on the tests' path (pytest's `pythonpath` setting in pyproject.toml): the independent
reference (`reference`, tests/reference/) and `helpers` (tests/helpers.py: the stand-in for the
engine and the small specs, which a test module also needs at import time or in another process)
import from there; the fixtures below give helpers' engine and spec.
"""
import math

import pytest
from helpers import SWEEP_SPEC, fake_engine, write_spec


@pytest.fixture
def faked_engine(monkeypatch):
    """The API and the CLI run helpers.fake_engine in place of the engine (forked workers inherit
    it); the fixture's value is that function."""
    from fencesweep.model import simulate as model_simulate

    monkeypatch.setattr(model_simulate, "simulate_resolved", fake_engine)
    return fake_engine


@pytest.fixture
def sweep_spec_file(tmp_path):
    """helpers.SWEEP_SPEC written to tmp_path / "s.yaml"; its path."""
    return write_spec(tmp_path, SWEEP_SPEC, "s.yaml")


def tip_depth(row, vals):
    """Depth of the fence tip in the load (docs/model.md §5.2, separating-axis edge choice), or 0."""
    L, A, l = vals["L"], vals["A"], vals["l"]
    c, s = math.cos(row.phi), math.sin(row.phi)
    to_local = lambda px, py: (c * (px - row.x) + s * (py - row.y), -s * (px - row.x) + c * (py - row.y))
    tx, ty = to_local(l * math.cos(row.alpha), l * math.sin(row.alpha))
    if abs(tx) >= L / 2 or abs(ty) >= A / 2:
        return 0.0
    ox, oy = to_local(0.0, 0.0)
    over_x = min(L / 2, max(ox, tx)) - max(-L / 2, min(ox, tx))
    over_y = min(A / 2, max(oy, ty)) - max(-A / 2, min(oy, ty))
    return L / 2 - abs(tx) if over_x < over_y else A / 2 - abs(ty)


def penetrations(row, vals):
    """Depth of every geometrically penetrated contact in a row (docs/model.md §5), by name."""
    L, A, l = vals["L"], vals["A"], vals["l"]
    ca, sa = math.cos(row.alpha), math.sin(row.alpha)
    c, s = math.cos(row.phi), math.sin(row.phi)
    out = {}
    for j, (lx, ly) in enumerate(((L / 2, A / 2), (-L / 2, A / 2), (-L / 2, -A / 2), (L / 2, -A / 2))):
        gx, gy = row.x + c * lx - s * ly, row.y + s * lx + c * ly
        sd, h = gx * ca + gy * sa, -gx * sa + gy * ca
        if 0 <= sd <= l and h < 0:
            out[f"fence{j}"] = -h
        if gx <= 0 and gy < 0:
            out[f"rail{j}"] = -gy
    tip = tip_depth(row, vals)
    if tip > 0:
        out["tip"] = tip
    return out


@pytest.fixture(name="tip_depth")
def _tip_depth():
    """tip_depth(row, vals): the fence tip's depth in the load of a trajectory row (docs/model.md §5.2)."""
    return tip_depth


@pytest.fixture(name="penetrations")
def _penetrations():
    """penetrations(row, vals): every penetrated contact's depth in a trajectory row (docs/model.md §5)."""
    return penetrations
