"""A spec too large to plan at once, swept in pieces into a Parquet dataset of parts
(fencesweep/study/spec/pieces.py, fencesweep/study/sweep/parts.py): the pieces are the spec's
scenes in order, the dataset reads back as the table of the whole spec swept at once, a killed run
keeps its finished parts, and nothing proportional to the whole spec is held."""
from __future__ import annotations

import pandas as pd
import pytest

import fencesweep
from fencesweep.errors import UsageError
from fencesweep.study.spec import pieces as SP
from fencesweep.study.sweep import estimate as EST
from fencesweep.study.sweep import output
from fencesweep.study.sweep import pipeline as sweep
from helpers import SWEEP_SPEC, fake_engine, load_spec

#: 40 scenes: 2 cases x drive 2 x B2 5 x K2 2 (SWEEP_SPEC)
MOST = 7


def test_pieces_are_the_scenes_in_order():
    spec = load_spec(SWEEP_SPEC)
    pieces = list(SP.pieces(spec, MOST))
    assert len(pieces) == SP.n_pieces(spec, MOST) > 1
    assert all(p.n_scenes <= MOST and p.whole is spec for p in pieces)
    assert [p.offset for p in pieces] == [sum(q.n_scenes for q in pieces[:k]) for k in range(len(pieces))]
    assert sum(p.n_scenes for p in pieces) == spec.n_scenes
    for p in pieces:
        for i in range(p.n_scenes):
            assert p.resolve(i) == spec.resolve(p.offset + i)
            assert p.describe(i) == spec.describe(p.offset + i)


def test_a_spec_that_fits_is_one_piece():
    spec = load_spec(SWEEP_SPEC)
    assert list(SP.pieces(spec)) == [spec] and SP.n_pieces(spec) == 1


def test_two_hundred_million_scenes_are_cut_into_pieces_not_refused(tmp_path):
    """B2 and K2 at 10,000 values each over two cases: planned piece by piece, each piece small."""
    spec = load_spec("""
        params: {drive: flexible}
        grid: {B2: {linspace: [0, 400, 10000]}, K2: {linspace: [100, 2100, 10000]}}
        cases: [small_far, long_near]
    """)
    assert spec.n_scenes == 200_000_000
    n = SP.n_pieces(spec)
    first = next(SP.pieces(spec))
    assert n == 2 * -(-10_000 // (SP.piece_limit() // 10_000)) and first.n_scenes <= SP.piece_limit()
    output.check_can_start(spec, tmp_path / "t.parquet")  # no UsageError: nothing too large to plan
    assert not (tmp_path / "t.parquet").exists()


def _sweep(tmp_path, name, monkeypatch, most=MOST, **kw):
    monkeypatch.setattr(SP, "PIECE_SCENES", most)
    return sweep.run_sweep(load_spec(SWEEP_SPEC), tmp_path / name, jobs=1, simulate=fake_engine, **kw)


def test_a_dataset_of_parts_reads_back_as_the_whole_table(tmp_path, monkeypatch):
    whole = _sweep(tmp_path, "whole.parquet", monkeypatch, most=10**6)
    res = _sweep(tmp_path, "parts.parquet", monkeypatch)
    assert res.out.is_dir() and res.n_scenes == whole.n_scenes == 40
    names = sorted(p.name for p in res.out.iterdir())
    assert names == [f"part-{k:05d}.parquet" for k in range(SP.n_pieces(load_spec(SWEEP_SPEC), MOST))]
    a, b = pd.read_parquet(whole.out), pd.read_parquet(res.out)
    pd.testing.assert_frame_equal(a, b)
    df = fencesweep.read_table(res.out)
    assert df.attrs["fencesweep"]["spec_hash"] == load_spec(SWEEP_SPEC).hash
    assert df.attrs["units"]["B2"] == "N m s/rad"
    pieces = [fencesweep.read_table(p).attrs["fencesweep"]["piece"] for p in sorted(res.out.iterdir())]
    assert [p["first_scene"] for p in pieces] == [p.offset for p in SP.pieces(load_spec(SWEEP_SPEC), MOST)]
    assert res.verify is not None and len(res.verify["pieces"]) == len(names)


def test_a_killed_dataset_run_keeps_its_finished_parts(tmp_path, monkeypatch):
    res = _sweep(tmp_path, "t.parquet", monkeypatch)
    first = (res.out / "part-00000.parquet").read_bytes()
    (res.out / "part-00002.parquet").unlink()  # as if killed in the third piece
    again = _sweep(tmp_path, "t.parquet", monkeypatch)
    assert again.computed > 0 and again.computed < res.computed  # only the missing piece
    assert (res.out / "part-00000.parquet").read_bytes() == first
    pd.testing.assert_frame_equal(pd.read_parquet(again.out), pd.read_parquet(res.out))
    assert not (res.out / "_work").exists()


def test_another_specs_dataset_is_not_replaced(tmp_path, monkeypatch):
    _sweep(tmp_path, "t.parquet", monkeypatch)
    other = load_spec(SWEEP_SPEC.replace("K2: [200, 570]", "K2: [200, 571]"))
    with pytest.raises(UsageError, match="holds the results of another spec"):
        sweep.run_sweep(other, tmp_path / "t.parquet", jobs=1, simulate=fake_engine)


def test_dry_run_of_a_spec_in_pieces_scales_its_first_piece(tmp_path, monkeypatch):
    monkeypatch.setattr(SP, "PIECE_SCENES", 10)
    spec = load_spec(SWEEP_SPEC)
    est = EST.estimate(spec, tmp_path / "t.parquet", jobs=1, simulate=fake_engine)
    assert est.pieces == 4 and est.n_scenes == 40 and est.seconds > 0
    assert any("4 pieces" in line for line in est.lines())
    assert not (tmp_path / "t.parquet").exists()
