"""A cycle you can watch (fencesweep/report/animation.py): `fencesweep run --animate FILE.gif` and
fencesweep.animate. The GIF read back with Pillow (frames, pixels, timing); the drawn load and fence
against the trajectory rows the frames show (the rectangle worked out here from x, y, phi); a
stream's loads, cycle by cycle; bad input refused with nothing written."""
import math
import sys

import numpy as np
import pytest

pytest.importorskip("matplotlib")
Image = pytest.importorskip("PIL.Image")

import fencesweep  # noqa: E402
from fencesweep.cli import main  # noqa: E402
from fencesweep.errors import UsageError  # noqa: E402
from fencesweep.model import params as P  # noqa: E402
from fencesweep.model.simulate import simulate_resolved  # noqa: E402
from fencesweep.report import animation as AN  # noqa: E402


def _rectangle(L, A, x, y, phi):
    """The load's corners (+L/2, +A/2), (-L/2, +A/2), (-L/2, -A/2), (+L/2, -A/2) turned by phi about (x, y)."""
    c, s = math.cos(phi), math.sin(phi)
    return np.array([(x + c * a - s * b, y + s * a + c * b)
                     for a, b in ((L / 2, A / 2), (-L / 2, A / 2), (-L / 2, -A / 2), (L / 2, -A / 2))])


def _drawn_load(ax):
    loads = [p for p in ax.patches if p.get_gid() == "load"]
    assert len(loads) == 1
    return loads[0].get_xy()[:4]


@pytest.fixture(scope="module")
def small_far():
    vals = P.resolve("cycle", "small_far")
    res, df = simulate_resolved(vals, trajectory=True)
    return vals, res, df


def test_a_small_gif_read_back(tmp_path):
    out = tmp_path / "c.gif"
    a = fencesweep.animate("cycle", "small_far", out=out, frames=6, fps=5, dpi=20, B2=40.0)
    assert a.path == out and a.frames == 6 and a.seconds == pytest.approx(1.2)
    assert a.results["outcome"] == fencesweep.simulate("cycle", "small_far", B2=40.0)["outcome"]
    im = Image.open(out)
    assert im.format == "GIF" and im.n_frames == 6
    assert im.size == a.size == (round(AN.FIGSIZE[0] * 20), round(AN.FIGSIZE[1] * 20))
    assert im.info["duration"] == 200 and im.info["loop"] == 0
    frames = []
    for k in range(im.n_frames):
        im.seek(k)
        frames.append(np.asarray(im.convert("RGB")))
    assert all((f != frames[0]).any() for f in frames[1:])  # the scene moves
    assert [p.name for p in tmp_path.iterdir()] == ["c.gif"]  # no temporary file left


def test_the_drawn_load_and_fence_follow_the_trajectory(small_far):
    vals, res, df = small_far
    frames = 12
    movie = AN.build(df, vals, res, frames, dpi=20)
    t = df["t"].to_numpy()
    peak = int(np.argmax(df["N_fence"].to_numpy()))
    assert peak in movie.rows  # the impact's largest force is one of the frames
    for k in range(frames):
        movie.draw(k)
        i = movie.rows[k]
        row = df.iloc[i]
        if i != peak:  # the first row at or after the frame's time
            assert t[i] >= movie.times[k] - 1e-12 and (i == 0 or t[i - 1] < movie.times[k] - 1e-12)
        assert f"t = {row['t']:.3f} s" in movie.ax.get_title()
        want = _rectangle(vals["L"], vals["A"], row["x"], row["y"], row["phi"])
        np.testing.assert_allclose(_drawn_load(movie.ax), want, atol=1e-12)
        tip = (vals["l"] * math.cos(row["alpha"]), vals["l"] * math.sin(row["alpha"]))
        ends = [tuple(ln.get_xydata()[-1]) for ln in movie.ax.lines]
        assert any(np.allclose(e, tip, atol=1e-12) for e in ends)
    assert len({float(df["x"].iloc[i]) for i in movie.rows}) >= 5  # the load is seen to move (until its exit)


def test_a_stream_draws_each_cycles_own_load(tmp_path):
    vals = P.resolve("stream", loads=["small_far", "long_near"])
    res, df = simulate_resolved(vals, trajectory=True)
    movie = AN.build(df, vals, res, 8, dpi=20)
    seen = set()
    for k in range(8):
        movie.draw(k)
        row = df.iloc[movie.rows[k]]
        c = int(row["cycle"])
        seen.add(c)
        L, A = (0.2, 0.1) if c == 0 else (0.7, 0.1)
        np.testing.assert_allclose(_drawn_load(movie.ax), _rectangle(L, A, row["x"], row["y"], row["phi"]),
                                   atol=1e-12)
        assert movie.ax.get_title().startswith(f"cycle {c + 1} of 2, t = ")
    assert seen == {0, 1}


def test_the_cli_writes_the_animation_of_its_run(tmp_path, monkeypatch, capsys):
    monkeypatch.setattr(AN, "FRAMES_PER_CYCLE", 3)
    out = tmp_path / "c.gif"
    assert main(["run", "--case", "small_far", "--animate", str(out)]) == 0
    assert f"animation written to {out} (3 frames" in capsys.readouterr().out
    assert Image.open(out).n_frames == 3


@pytest.mark.parametrize("name", ["c.avi", "c.png", "c"])
def test_a_bad_suffix_is_refused_with_nothing_written(tmp_path, capsys, name):
    assert main(["run", "--case", "small_far", "--animate", str(tmp_path / name)]) == 2
    err = capsys.readouterr().err
    assert repr(str(tmp_path / name)) in err and ".gif" in err and ".mp4" in err
    assert list(tmp_path.iterdir()) == []


def test_an_mp4_without_ffmpeg_is_refused_with_nothing_written(tmp_path, capsys, monkeypatch):
    from matplotlib import animation

    monkeypatch.setattr(animation.writers, "is_available", lambda name: False)
    out = tmp_path / "c.mp4"
    assert main(["run", "--case", "small_far", "--animate", str(out), "--trajectory",
                 str(tmp_path / "t.parquet")]) == 2
    err = capsys.readouterr().err
    assert repr(str(out)) in err and "ffmpeg" in err and ".gif" in err
    assert list(tmp_path.iterdir()) == []
    with pytest.raises(UsageError, match="ffmpeg"):
        fencesweep.animate("cycle", "small_far", out=out)
    assert list(tmp_path.iterdir()) == []


def test_without_matplotlib_the_extra_is_named(tmp_path, capsys, monkeypatch):
    monkeypatch.setitem(sys.modules, "matplotlib", None)
    monkeypatch.setitem(sys.modules, "matplotlib.animation", None)
    out = tmp_path / "c.gif"
    assert main(["run", "--case", "small_far", "--animate", str(out)]) == 2
    assert "pip install 'fencesweep[plot]'" in capsys.readouterr().err
    with pytest.raises(ImportError, match=r"fencesweep\[plot\]"):
        fencesweep.animate("cycle", "small_far", out=out)
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("kwargs, named", [({"frames": 1}, "frames = 1"), ({"fps": 0}, "fps = 0"),
                                           ({"dpi": 2.5}, "dpi = 2.5"), ({"scene": "impact"}, "'impact'"),
                                           ({"B2": -1.0}, "B2")])
def test_bad_arguments_are_refused_before_anything_runs(tmp_path, kwargs, named):
    kwargs = {"scene": "cycle", "case": "small_far", **kwargs}
    with pytest.raises((UsageError, fencesweep.ParameterError), match=named):
        fencesweep.animate(out=tmp_path / "c.gif", **kwargs)
    assert list(tmp_path.iterdir()) == []
