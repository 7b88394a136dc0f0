"""`fencesweep run`: one scene, its results printed (a table, or one JSON object with --json), its
time series written with --trajectory and drawn with --animate (report/animation.py); cli.py
registers it. No physics and no orchestration here: it parses, calls fencesweep.model.simulate
and prints.

Bad input prints one clear message (the parameter, the value, what is allowed) and exits with
code 2; nothing runs then.
"""
from __future__ import annotations

import argparse
import json
import math

from fencesweep.errors import UsageError
from fencesweep.model import params as P


def add_run_parser(sub) -> argparse.ArgumentParser:
    """Register `fencesweep run` on the CLI's subparsers."""
    run = sub.add_parser("run", help="simulate one scene and print its results")
    run.add_argument("--scene", default="cycle", choices=P.SCENES)
    run.add_argument("--case", default=None, choices=tuple(P.CASES))
    run.add_argument("--set", action="append", default=[], metavar="NAME=VALUE",
                     help="override a parameter of docs/model.md §12 (repeatable)")
    run.add_argument("--json", action="store_true", help="print one JSON object (an undefined result, e.g. t_first_contact without contact, is null)")
    run.add_argument("--trajectory", metavar="PATH.parquet", help="write the time series for plotting "
                     "(a stream's: the whole stream, with a cycle column)")
    run.add_argument("--animate", metavar="FILE.gif", default=None,
                     help="write the cycle (a stream: its cycles one after another) as an animation: load, fence, "
                          "drive lever, belt, contact forces, time and stage; .gif, or .mp4 where ffmpeg is "
                          "installed (needs matplotlib: pip install 'fencesweep[plot]')")
    run.add_argument("--loads", metavar="CASES|FILE.csv", default=None,
                     help="scene stream: one load per cycle, named cases separated by commas "
                          "(small_far,long_near,...) or a CSV file with columns among L, A, m1, dP, R_s, phi0")
    run.set_defaults(func=cmd_run)
    return run


def _parse_sets(items: list[str]) -> dict:
    """--set NAME=VALUE (repeated) as {name: value}, each value parsed as its parameter's type."""
    out = {}
    for item in items or []:
        if "=" not in item:
            raise UsageError(f"--set {item!r} is not NAME=VALUE (e.g. --set B2=40)")
        name, text = item.split("=", 1)
        out[name.strip()] = P.parse_value(name.strip(), text.strip())
    return out


def _fmt(value) -> str:
    """A result for the table: a float to 6 significant digits, NaN as nan, the rest as str."""
    if isinstance(value, float):
        if math.isnan(value):
            return "nan"
        return f"{value:.6g}"
    return str(value)


def _json_value(value):
    """A result as JSON: an undefined number (NaN, e.g. t_first_contact of a run without
    contact) and an infinite one, which JSON cannot hold, become null; numpy scalars plain."""
    if hasattr(value, "item"):
        value = value.item()
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value


def cmd_run(args: argparse.Namespace) -> int:
    """`fencesweep run`: resolve the scene (bad input raises before anything runs), simulate it,
    write --trajectory and --animate, print the results."""
    from fencesweep.model import simulate as api
    from fencesweep.model.results import SCENE_RESULTS, UNITS

    overrides = _parse_sets(args.set)
    if args.loads is not None and args.scene != "stream":
        raise UsageError("--loads is only available for --scene stream")
    loads = _parse_loads(args.loads)
    vals = P.resolve(args.scene, args.case, loads=loads, **overrides)  # raises before anything runs
    _check_run_outputs(args)
    res, traj = api.simulate_resolved(vals, trajectory=bool(args.trajectory or args.animate))
    if args.trajectory:
        from fencesweep.study.store.table import write_trajectory

        summary = {k: v for k, v in res.items() if k != "cycles"}
        write_trajectory(traj, args.trajectory, dict(vals, loads=None if loads is None else list(vals["loads"])),
                         summary)
    anim = None
    if args.animate:
        from fencesweep.report.animation import write_animation

        anim = write_animation(traj, vals, res, args.animate)
    if args.scene == "stream":
        _print_stream(args, res, traj, anim)
        return 0
    if args.json:
        print(json.dumps({k: _json_value(v) for k, v in res.items()}, allow_nan=False))
    else:
        width = max(len(n) for n, _, _ in SCENE_RESULTS[args.scene])
        head = f"scene {args.scene}" + (f", case {args.case}" if args.case else "")
        print(head)
        for name, _, _ in SCENE_RESULTS[args.scene]:
            unit = UNITS.get(name, "-")
            unit = "" if unit == "-" else f" {unit}"
            print(f"  {name:<{width}}  {_fmt(res[name])}{unit}")
        if args.trajectory:
            print(f"trajectory written to {args.trajectory} ({len(traj)} rows)")
        _print_animation(anim)
    return 0


def _check_run_outputs(args: argparse.Namespace) -> None:
    """--trajectory and --animate, checked before anything runs: a cycle's or a stream's, and a file
    of the right kind (--animate: a .gif, or an .mp4 where ffmpeg is installed; matplotlib there)."""
    for flag, value in (("--trajectory", args.trajectory), ("--animate", args.animate)):
        if value and args.scene not in ("cycle", "stream"):
            raise UsageError(f"{flag} is only available for --scene cycle and --scene stream")
    if args.trajectory and not args.trajectory.endswith(".parquet"):
        raise UsageError(f"--trajectory {args.trajectory!r} must end with .parquet")
    if args.animate:
        from fencesweep.report.animation import PLOT_EXTRA, check_output

        try:
            check_output(args.animate, "--animate")
        except ImportError:
            raise UsageError(f"--animate needs matplotlib, which is not installed: {PLOT_EXTRA}") from None


def _print_animation(a) -> None:
    """The line that says where --animate wrote the animation (a: report.animation.Animation, or None)."""
    if a is not None:
        print(f"animation written to {a.path} ({a.frames} frames, {a.seconds:g} s at {a.fps:g} frames/s)")


def _parse_loads(text: str | None):
    """--loads: named cases separated by commas (small_far,long_near,...) or a CSV file whose
    columns are among params.LOAD_NAMES, one row per cycle."""
    if text is None:
        return None
    if text.endswith(".csv"):
        import pandas as pd

        try:
            return pd.read_csv(text)
        except (OSError, ValueError) as exc:
            raise UsageError(f"--loads {text!r}: cannot read it as a CSV table of loads ({exc})") from None
    return [name.strip() for name in text.split(",")]


#: the columns of a stream's per-cycle table on the terminal (all of them: --json)
STREAM_COLUMNS = ("outcome", "t_exit", "overload", "deflection_max", "residual_amplitude", "start_deflection",
                  "start_amplitude", "contact_time", "n_steps")


def _print_stream(args: argparse.Namespace, res: dict, traj, anim=None) -> None:
    """A stream's results (docs/model.md §14): the summary and the per-cycle table, or one JSON object."""
    from fencesweep.model.results import STREAM_RESULTS, UNITS

    cycles = res["cycles"]
    if args.json:
        out = {n: _json_value(res[n]) for n, _, _ in STREAM_RESULTS}
        out["cycles"] = [{k: _json_value(v) for k, v in row.items()} for row in cycles.to_dict("records")]
        print(json.dumps(out, allow_nan=False))
        return
    print("scene stream" + (f", case {args.case}" if args.case else ""))
    width = max(len(n) for n, _, _ in STREAM_RESULTS)
    for name, _, _ in STREAM_RESULTS:
        unit = UNITS.get(name, "-")
        print(f"  {name:<{width}}  {_fmt(res[name])}{'' if unit == '-' else ' ' + unit}")
    heads = ["cycle"] + [f"{c} [{UNITS[c]}]" if UNITS[c] != "-" else c for c in STREAM_COLUMNS]
    rows = [[str(k)] + [_fmt(row[c]) for c in STREAM_COLUMNS] for k, row in cycles.iterrows()]
    widths = [max(len(h), *(len(r[i]) for r in rows)) for i, h in enumerate(heads)]
    print("  ".join(h.rjust(w) for h, w in zip(heads, widths)))
    for r in rows:
        print("  ".join(v.rjust(w) for v, w in zip(r, widths)))
    if args.trajectory:
        print(f"trajectory written to {args.trajectory} ({len(traj)} rows, {len(cycles)} cycles)")
    _print_animation(anim)
