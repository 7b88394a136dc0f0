"""A cycle you can watch: `fencesweep run ... --animate FILE.gif` and `fencesweep.animate(...)`.

The frames are the trajectory that `fencesweep run --trajectory` writes (model/simulate.py
simulate_resolved), drawn one row at a time by the cycle frames' own function
(figures_cycle.draw_frame): the belt, the rail, the load, the fence, its drive lever, the contact
forces (scaled as in cycle_<case>.png), the time and the stage. Drawing only: no physics here.
Frame k shows the first trajectory row at or after the k-th of `frames` times evenly spaced over the
run (the title gives that row's time; where the engine's steps are longer than the frames' spacing,
two frames show one row), except that the frame nearest each cycle's largest fence force and
largest rail force shows that row (an impact lasts milliseconds, less than a frame's spacing); a
stream's cycles follow one another. Each frame is numbered in its lower right corner, so that no
two are alike (a GIF would merge them into one).

A .gif is written with Pillow, an .mp4 with ffmpeg where matplotlib finds it. matplotlib is the
optional extra `[plot]`; it is imported inside the functions, so this module imports without it.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable, NamedTuple

import numpy as np

from fencesweep.errors import UsageError
from fencesweep.report import figures_cycle as FC

#: frames per work cycle (a stream: times its number of cycles, at most MAX_DEFAULT_FRAMES), frames
#: per second (10: a GIF keeps a frame's time in hundredths of a second) and dots per inch
FRAMES_PER_CYCLE = 60
MAX_DEFAULT_FRAMES = 1200
FPS = 10.0
DPI = 80
#: the figure's size [in]: 512 x 448 pixels at DPI (even numbers, as an .mp4's encoder wants)
FIGSIZE = (6.4, 5.6)
#: the files an animation can be written to, by their suffix
SUFFIXES = (".gif", ".mp4")
#: the scenes that have a trajectory to draw
SCENES = ("cycle", "stream")
PLOT_EXTRA = "pip install 'fencesweep[plot]'"


@dataclass(frozen=True)
class Animation:
    """What animate wrote: the file, its frame count, frames per second, size in pixels (width,
    height) and the run's results (those of fencesweep.simulate)."""

    path: Path
    frames: int
    fps: float
    size: tuple
    results: dict

    @property
    def seconds(self) -> float:
        """How long the animation plays [s]."""
        return self.frames / self.fps


class Movie(NamedTuple):
    """An animation before it is written: the figure, its axes, the frames' times (frame_rows: evenly
    spaced, a peak's frame at its row's time), the trajectory row each frame draws and draw(k), which
    draws frame k on the axes."""

    fig: Any
    ax: Any
    times: np.ndarray
    rows: list
    draw: Callable[[int], None]


def animate(scene: str = "cycle", case: str | None = None, *, out, frames: int | None = None, fps: float = FPS,
            dpi: int = DPI, **params: Any) -> Animation:
    """Simulate a cycle or a stream as fencesweep.simulate(scene, case, **params) does and write it as
    an animation to `out` (.gif; .mp4 where ffmpeg is installed).

    frames: how many (default FRAMES_PER_CYCLE per work cycle, at most MAX_DEFAULT_FRAMES), at `fps`
    frames per second and `dpi` dots per inch (FIGSIZE inches). Returns an Animation (the path,
    frames, fps, size in pixels and the run's results). Bad input raises UsageError (the output,
    frames, fps, dpi, a scene without a trajectory) or ParameterError (a parameter) before anything
    runs or is written; without matplotlib, an ImportError that names the extra to install.
    """
    from fencesweep.model import params as P
    from fencesweep.model.simulate import simulate_resolved

    check_options(frames, fps, dpi)
    vals = P.resolve(scene, case, **params)
    check_scene(vals["scene"], "scene =")
    path = check_output(out, "out =")  # the last check: it makes the output's directory
    results, traj = simulate_resolved(vals, trajectory=True)
    return write_animation(traj, vals, results, path, frames=frames, fps=fps, dpi=dpi)


# ---------------------------------------------------------------------------- checks (before anything runs)
def matplotlib_animation():
    """matplotlib.animation, or an ImportError that names the extra to install."""
    try:
        from matplotlib import animation
    except ImportError as exc:
        raise ImportError(f"an animation needs matplotlib, which is not installed: {PLOT_EXTRA}") from exc
    return animation


def check_output(out, name: str) -> Path:
    """The animation's path, checked: a .gif, or an .mp4 where matplotlib finds ffmpeg, in a
    directory that can be written (made if it is missing, as --trajectory's and grid's --out are);
    `name` is how the message names it ("--animate", "out =")."""
    path = Path(out)
    suffix = path.suffix.lower()
    if suffix not in SUFFIXES:
        raise UsageError(f"{name} {str(out)!r} is not allowed: an animation is a .gif file "
                         f"(or .mp4 where ffmpeg is installed)")
    animation = matplotlib_animation()
    if suffix == ".mp4" and not animation.writers.is_available("ffmpeg"):
        raise UsageError(f"{name} {str(out)!r} is not allowed here: an .mp4 needs ffmpeg, which matplotlib does "
                         f"not find on this machine; allowed here: .gif (or install ffmpeg on the PATH)")
    from fencesweep.study.sweep.output import check_writable

    check_writable(path)
    return path


def check_options(frames, fps, dpi) -> None:
    """frames (None or an integer >= 2), fps (a number > 0) and dpi (an integer >= 10), or UsageError."""
    if frames is not None and (isinstance(frames, bool) or not isinstance(frames, (int, np.integer)) or frames < 2):
        raise UsageError(f"frames = {frames!r} is not allowed: frames must be an integer >= 2 (or None)")
    if isinstance(fps, bool) or not isinstance(fps, (int, float)) or not math.isfinite(fps) or fps <= 0:
        raise UsageError(f"fps = {fps!r} is not allowed: fps must be a number > 0")
    if isinstance(dpi, bool) or not isinstance(dpi, (int, np.integer)) or dpi < 10:
        raise UsageError(f"dpi = {dpi!r} is not allowed: dpi must be an integer >= 10")


def check_scene(scene: str, name: str) -> None:
    """Only a cycle and a stream have a trajectory to draw."""
    if scene not in SCENES:
        raise UsageError(f"{name} {scene!r} cannot be animated: only the scenes {' and '.join(SCENES)} have a "
                         f"trajectory to draw")


# ---------------------------------------------------------------------------- frames
#: the forces whose largest value in each cycle a frame shows, and that frame's label
PEAKS = (("N_fence", "largest fence force"), ("N_rail", "largest rail force"))


def peak_rows(df) -> dict:
    """{row: label} of each cycle's largest fence force and largest rail force (where there is one)."""
    cycles = df.groupby("cycle") if "cycle" in df.columns else [(0, df)]
    out = {}
    for _, part in cycles:
        for col, label in PEAKS:
            if float(part[col].max()) > 0:
                out[df.index.get_loc(part[col].idxmax())] = label
    return out


def frame_rows(df, frames: int) -> tuple:
    """(times, rows): `frames` times evenly spaced over the trajectory and the row each draws
    (figures_cycle.row_at: the first at or after it); the frame nearest a peak_rows row draws
    that row instead (its time becomes the row's)."""
    t = df["t"].to_numpy()
    times = np.linspace(t[0], t[-1], frames)
    rows = [FC.row_at(t, tt) for tt in times]
    step = times[1] - times[0]
    for i in sorted(peak_rows(df)):
        k = min(int(round((t[i] - t[0]) / step)), frames - 1) if step > 0 else 0
        times[k], rows[k] = t[i], i
    return times, rows


def load_size(vals: dict, cycle: int) -> tuple:
    """(L, A) of the load of `cycle`: a stream's own list of loads, else the scene's load."""
    loads = vals.get("loads")
    if loads is None:
        return float(vals["L"]), float(vals["A"])
    return float(loads[cycle][0]), float(loads[cycle][1])


def _element_text(vals: dict) -> str:
    """The fence: rigid, free, or flexible with its B2 and K2."""
    if vals["drive"] == "flexible":
        return f"flexible fence B2 = {vals['B2']:g}, K2 = {vals['K2']:g}"
    return {"rigid": "rigid fence", "free": "free fence (B2 = K2 = 0)"}.get(vals["drive"], f"{vals['drive']} fence")


def suptitle(vals: dict, results: dict) -> str:
    """The animation's heading: the run (scene, case, load), the fence and working point, the outcome."""
    case = f" (case {vals['case']})" if vals.get("case") else ""
    point = f"{_element_text(vals)}; t_c = {vals['t_c']:g} s, v = {vals['v']:g} m/s"
    if vals["scene"] == "stream":
        n = int(vals["n_cycles"])
        head = f"{n} sorting cycles back to back{case}, one every {vals['period']:g} s"
        tail = f"{results['n_scraped']} of {n} scraped, worst overload {results['worst_overload']:.2f}"
    else:
        head = f"One sorting cycle{case}: {vals['L']:g} x {vals['A']:g} m load, {vals['dP']:g} m from the rail"
        tail = f"outcome {results['outcome']} at t = {results['t_exit']:.3f} s, overload {results['overload']:.2f}"
    return f"{head}\n{point}\n{tail}"


def _frame_title(df, vals: dict, i: int, label: str) -> str:
    """Frame title of row i: the time, the label, the stage (figures_cycle.frame_title); a stream's cycle."""
    row = df.iloc[i]
    if vals["scene"] != "stream":
        return FC.frame_title(row, "", label)
    k = int(row["cycle"])
    into = f"{float(row['t']) - k * float(vals['period']):.3f} s into it"
    return FC.frame_title(row, f"cycle {k + 1} of {int(vals['n_cycles'])}, ", into + (f", {label}" if label else ""))


def build(df, vals: dict, results: dict, frames: int, dpi: int = DPI) -> Movie:
    """The figure of an animation of trajectory df (vals: the run's resolved parameters, results:
    its results) and draw(k), which draws frame k with figures_cycle.draw_frame."""
    from matplotlib.figure import Figure

    fig = Figure(figsize=FIGSIZE, dpi=dpi)
    ax = fig.add_axes((0.09, 0.2, 0.88, 0.63))
    fig.suptitle(suptitle(vals, results), fontsize=8, y=0.99, va="top")
    fig.legend(handles=FC.legend_handles(), loc="lower center", ncol=2, fontsize=7, frameon=False,
               bbox_to_anchor=(0.5, 0.0))
    times, rows = frame_rows(df, frames)
    labels = peak_rows(df)
    nmax = FC.largest_force(df)
    stream = vals["scene"] == "stream"
    counter = fig.text(0.995, 0.005, "", ha="right", va="bottom", fontsize=6, color="0.5")

    def draw(k: int) -> None:
        counter.set_text(f"frame {k + 1}/{frames}")
        i = rows[k]
        row = df.iloc[i]
        L, A = load_size(vals, int(row["cycle"]) if stream else 0)
        ax.clear()
        title = _frame_title(df, vals, i, labels.get(i, ""))
        FC.draw_frame(ax, dict(P_max=vals["P_max"], l=vals["l"], L=L, A=A), row, nmax, title)
        ax.set_xlabel("x along the belt [m]; arrow heads at the point of action, length ~ sqrt(force)", fontsize=7)
        ax.set_ylabel("y across the belt [m]", fontsize=7)

    return Movie(fig, ax, times, rows, draw)


def default_frames(vals: dict) -> int:
    """FRAMES_PER_CYCLE per work cycle, at most MAX_DEFAULT_FRAMES."""
    return min(FRAMES_PER_CYCLE * (int(vals["n_cycles"]) if vals["scene"] == "stream" else 1), MAX_DEFAULT_FRAMES)


def write_animation(df, vals: dict, results: dict, out, frames: int | None = None, fps: float = FPS,
                    dpi: int = DPI) -> Animation:
    """Write trajectory df (a run of vals with these results) as an animation to `out` (checked by
    check_output), atomically: a failed write leaves nothing there. Returns the Animation."""
    from fencesweep.study.store.table import atomic_path

    animation = matplotlib_animation()
    frames = default_frames(vals) if frames is None else int(frames)
    movie = build(df, vals, results, frames, dpi)
    path = Path(out)
    writer = animation.PillowWriter(fps=fps) if path.suffix.lower() == ".gif" else animation.FFMpegWriter(fps=fps)
    anim = animation.FuncAnimation(movie.fig, movie.draw, frames=frames, init_func=lambda: None, repeat=False)
    with atomic_path(path, fsync=False) as tmp:
        anim.save(str(tmp), writer=writer, dpi=dpi)
    return Animation(path, frames, float(fps), tuple(movie.fig.canvas.get_width_height()), results)
