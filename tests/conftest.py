"""Helpers shared by the test files, as fixtures (a test file never imports another).

tests/ is on the tests' path (pytest's `pythonpath` setting in pyproject.toml): the independent
reference (`reference`, tests/reference/) and `helpers` (tests/helpers.py: the stand-in for the
engine, the small specs and the kernels' first runs, which a test module also needs at import time
or in another process) import from there; the fixtures below give helpers' engine, spec and first
runs.
"""
import contextlib
import json
import math
import os
from pathlib import Path

import pytest
from filelock import FileLock
from helpers import (SWEEP_SPEC, background_result, fake_engine, first_run_here, first_run_pair,
                     wait_for_background, write_spec)


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


def once_per_session(tmp_path_factory, name: str, compute):
    """compute(folder)'s JSON value, computed once per test session even on several xdist workers:
    the first worker to ask computes it under a lock in the session's shared temporary directory
    and keeps it there; a worker that asks later (or while it runs) reads it."""
    root = tmp_path_factory.getbasetemp()
    if os.environ.get("PYTEST_XDIST_WORKER"):
        root = root.parent  # the session's directory, above each worker's own
    done = root / f"{name}.json"
    with FileLock(root / f"{name}.lock"):
        if not done.exists():
            folder = root / name
            folder.mkdir(exist_ok=True)
            done.write_text(json.dumps(compute(folder)))
        return json.loads(done.read_text())


@pytest.fixture(scope="session", autouse=True)
def _first_run_pair_before_any_test(request, tmp_path_factory):
    """When the session reads the first runs (`first_runs`), their pair (helpers.first_run_pair)
    runs before any test, on every xdist worker: the first worker to get here runs it while the
    others wait for it (the cores are busy meanwhile: the compiling process, its helper, and the
    process that compiles alone in the background). On a new clone the pair compiles the kernels
    into the cache the tests use, which they then load instead of compiling them once more; and no
    test compiles in that cache while the pair does (the pair's processes must be the ones that
    compile there). Should the pair raise, only the tests that read it fail: `first_runs` asks
    again. At the session's end the worker that started the background process waits for it."""
    if any("first_runs" in item.fixturenames for item in request.session.items):
        with contextlib.suppress(Exception):
            once_per_session(tmp_path_factory, "first_run_pair", first_run_pair)
    yield
    wait_for_background()


@pytest.fixture(scope="session", name="first_runs")
def _first_runs(tmp_path_factory):
    """The kernels' first runs in new processes, run once per session for tests/test_jit.py and
    tests/test_compile_isolation.py (helpers.first_run_pair): "pair", two started at once on an
    empty cache (before any test, above); "alone", one compiling alone on another (in the
    background meanwhile); "here", the same runs on this checkout's cache."""
    cold = once_per_session(tmp_path_factory, "first_run_pair", first_run_pair)
    here = cold["here"] or once_per_session(tmp_path_factory, "first_run_here", first_run_here)
    return {**cold, "here": here, "alone": background_result(Path(cold["alone_file"]))}


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


def _fence_in_load(o, t, L, A, grow):
    """The fence O-T inside the load (the load's frame), [u_a, u_b] and the edges cutting its ends."""
    lo, hi, e_lo, e_hi = 0.0, 1.0, -1, -1
    def margin(p, e):
        return (L / 2 - p[0], L / 2 + p[0], A / 2 - p[1], A / 2 + p[1])[e] + grow
    for e in range(4):
        c0, c1 = margin(o, e), margin(t, e) - margin(o, e)
        if c1 > 0 and -c0 / c1 > lo:
            lo, e_lo = -c0 / c1, e
        elif c1 < 0 and -c0 / c1 < hi:
            hi, e_hi = -c0 / c1, e
        elif c1 == 0 and c0 < 0:
            return None
    return (lo, hi, e_lo, e_hi) if lo <= hi else None


def fence_manifold(row, vals):
    """The depths of the fence's manifold points in a trajectory row (docs/model.md §5.2, written
    here apart from the engine, every corner on the fence's +n side): the axis of least
    penetration among the fence's face (corners in the span, the point under the tip, measured
    as its edge measures the tip within 1 %: (5.7)) and the load's four edges (the deeper end of
    the fence inside the load); [] when the fence misses it."""
    L, A, l = vals["L"], vals["A"], vals["l"]
    ca, sa = math.cos(row.alpha), math.sin(row.alpha)
    c, s = math.cos(row.phi), math.sin(row.phi)
    loc = [(L / 2, A / 2), (-L / 2, A / 2), (-L / 2, -A / 2), (L / 2, -A / 2)]
    G = [(row.x + c * lx - s * ly, row.y + s * lx + c * ly) for lx, ly in loc]
    sh = [(gx * ca + gy * sa, -gx * sa + gy * ca) for gx, gy in G]
    to_local = lambda px, py: (c * (px - row.x) + s * (py - row.y), -s * (px - row.x) + c * (py - row.y))
    o, t = to_local(0.0, 0.0), to_local(l * ca, l * sa)
    inside = _fence_in_load(o, t, L, A, 1e-10 * l)
    if inside is None:
        return []
    lo, hi, e_lo, e_hi = inside
    ends = [(o[0] + u * (t[0] - o[0]), o[1] + u * (t[1] - o[1])) for u in (lo, hi)]
    margins = [[(L / 2 - p[0], L / 2 + p[0], A / 2 - p[1], A / 2 + p[1])[e] for p in ends] for e in range(4)]
    if any(max(-1.0 if e_lo == e else m[0], -1.0 if e_hi == e else m[1]) <= -1e-10 * l
           for e, m in enumerate(margins)):
        return []
    face = [-h for sd, h in sh if 0 <= sd <= l]
    u_own, u_edge, beyond = -math.inf, -1, -math.inf
    for i in range(4):
        (si, hi_), (sj, hj) = sh[i], sh[(i + 1) % 4]
        if (si < l) != (sj < l):
            (sc, hc), (sb, hb) = ((si, hi_), (sj, hj)) if si < l else ((sj, hj), (si, hi_))
            own = -(hc + (l - sc) / (sb - sc) * (hb - hc))
            if own > u_own:
                u_own, beyond, u_edge = own, -hb, (2, 1, 3, 0)[i]  # the edge (5.8) from corner i
    m_u = u_own  # U as its edge measures the tip end, while the two agree within 1 %
    under = None  # U: the tip end below its edge, or the corner beyond the tip if shallower
    if u_edge >= 0 and e_hi != u_edge:
        m_u = max(margins[u_edge][1], 0.99 * u_own)
        under = min(margins[u_edge][1], beyond)
    m_face = max(face + [m_u])
    bias = -1e-10 * l if any(d > 0 for d in face) else 1e-10 * l  # the face wins ties while a corner touches
    best, depths = m_face + bias, [d for d in face + ([under] if under is not None else []) if d > 0]
    for e in range(4):
        cand = [m for k, m in enumerate(margins[e]) if (e_lo, e_hi)[k] != e]
        if cand and max(cand) < best:
            best, depths = max(cand), [max(cand)] if max(cand) > 0 else []
    return sorted(depths, reverse=True)


def penetrations(row, vals):
    """Depth of every penetrated contact in a row (docs/model.md §5), by name: the fence's
    manifold points by rank ("m0" the deepest), the rail's corners."""
    out = {f"m{k}": d for k, d in enumerate(fence_manifold(row, vals))}
    c, s = math.cos(row.phi), math.sin(row.phi)
    for j, (lx, ly) in enumerate(((vals["L"] / 2, vals["A"] / 2), (-vals["L"] / 2, vals["A"] / 2),
                                  (-vals["L"] / 2, -vals["A"] / 2), (vals["L"] / 2, -vals["A"] / 2))):
        gx, gy = row.x + c * lx - s * ly, row.y + s * lx + c * ly
        if gx <= 0 and gy < 0:
            out[f"rail{j}"] = -gy
    return out


@pytest.fixture(name="tip_depth")
def _tip_depth():
    """tip_depth(row, vals): the fence tip's depth in the load of a trajectory row (docs/model.md §5.2)."""
    return tip_depth


@pytest.fixture(name="penetrations")
def _penetrations():
    """penetrations(row, vals): every penetrated contact's depth in a trajectory row (docs/model.md §5)."""
    return penetrations
