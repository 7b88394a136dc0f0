"""The command line: `fencesweep run | grid | plot`. No physics here.

Bad input prints one clear message (the parameter, the value, what is allowed) and exits
with code 2; nothing runs then.
"""
from __future__ import annotations

import argparse
import json
import math
import sys

from . import params as P


class UsageError(ValueError):
    """A command-line mistake that is not about a parameter value."""


def _parse_sets(items: list[str]) -> dict:
    out = {}
    for item in items or []:
        if "=" not in item:
            raise UsageError(f"--set {item!r} is not NAME=VALUE (e.g. --set B2=40)")
        name, text = item.split("=", 1)
        out[name.strip()] = P.parse_value(name.strip(), text.strip())
    return out


def _fmt(value) -> str:
    if isinstance(value, float):
        if math.isnan(value):
            return "nan"
        return f"{value:.6g}"
    return str(value)


def cmd_run(args: argparse.Namespace) -> int:
    from . import api
    from .results import SCENE_RESULTS, UNITS

    overrides = _parse_sets(args.set)
    vals = P.resolve(args.scene, args.case, **overrides)  # raises before anything runs
    traj = None
    if args.trajectory:
        if args.scene != "cycle":
            raise UsageError("--trajectory is only available for --scene cycle")
        if not args.trajectory.endswith(".parquet"):
            raise UsageError(f"--trajectory {args.trajectory!r} must end with .parquet")
    res, traj = api.simulate_resolved(vals, trajectory=bool(args.trajectory))
    if args.trajectory:
        from .store import write_trajectory

        write_trajectory(traj, args.trajectory, vals, res)
    if args.json:
        print(json.dumps(res, default=float))
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
    return 0


def build_parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(prog="fencesweep", description="Active rotary fence: one cycle, or sweeps of many.")
    sub = ap.add_subparsers(dest="command", required=True)

    run = sub.add_parser("run", help="simulate one scene and print its results")
    run.add_argument("--scene", default="cycle", choices=P.SCENES)
    run.add_argument("--case", default=None, choices=tuple(P.CASES))
    run.add_argument("--set", action="append", default=[], metavar="NAME=VALUE",
                     help="override a parameter of MODEL.md §12 (repeatable)")
    run.add_argument("--json", action="store_true", help="print one JSON object")
    run.add_argument("--trajectory", metavar="PATH.parquet", help="write the time series for plotting")
    run.set_defaults(func=cmd_run)

    from .plots import add_plot_parser  # matplotlib is imported only when a plot is drawn
    from .sweep import add_grid_parser

    add_grid_parser(sub)
    add_plot_parser(sub)
    return ap


def main(argv: list[str] | None = None) -> int:
    ap = build_parser()
    args = ap.parse_args(argv)
    try:
        return int(args.func(args) or 0)
    except (P.ParameterError, UsageError) as exc:
        print(f"fencesweep: error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
