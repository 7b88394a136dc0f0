"""`fencesweep risk SPEC`: the command line of the risk study (sweeps/README.md, Risk from a parcel
mix). It parses, calls fencesweep.study.api.risk and prints one line per marked element and a
summary; cli.py registers it. No physics and no orchestration here."""
from __future__ import annotations

import argparse
import logging
import sys

from fencesweep.errors import UsageError, WriteError


def _say(msg: str) -> None:
    """A note or a summary through the "fencesweep" logger, which the CLI shows on stderr (cli._say)."""
    log = logging.getLogger("fencesweep")
    (log.warning if msg.startswith("warning") else log.info)(msg)


def add_risk_parser(sub) -> argparse.ArgumentParser:
    g = sub.add_parser(
        "risk", help="how many parcels in 10,000 of a mix each element hits too hard or does not sort",
        description="Sample a risk spec's parcel population (sweeps/README.md, Risk from a parcel mix) for every "
                    "element and operating point, round by round until P(any constraint broken) is known to lie "
                    "below or above p_max (or the cap is reached), and write one Parquet row per element and "
                    "operating point with P(overload > limit), P(not scraped), P(deflection_max > limit), "
                    "P(residual_amplitude > limit), P(any) and their intervals. A killed run, rerun, keeps its "
                    "rounds' cycles.")
    g.add_argument("spec", metavar="SPEC.yaml", help="the risk spec (e.g. sweeps/risk.yaml)")
    g.add_argument("--out", metavar="PATH.parquet", help="output table (default: the spec's output)")
    g.add_argument("--jobs", type=int, default=None, metavar="N", help="worker processes (default: all cores)")
    g.add_argument("--no-resume", action="store_true", help="discard the cycles of an interrupted run")
    g.add_argument("--overwrite", action="store_true", help="replace a table that is not this spec's at the output")
    g.add_argument("--backend", choices=("loky", "dask"), default="loky",
                   help="loky: processes on this machine; dask: a Dask cluster (needs --scheduler)")
    g.add_argument("--scheduler", metavar="ADDRESS", help="Dask scheduler, e.g. tcp://HOST:8786")
    g.add_argument("--wait", action="store_true",
                   help="if another run is writing the same output, wait for it (default: refuse at once)")
    g.add_argument("--quiet", action="store_true", help="no progress bar and no summary")
    g.set_defaults(func=cmd_risk)
    return g


def _line(row) -> str:
    name = row["label"] if isinstance(row["label"], str) else "least risk (the lowest upper end)"
    return (f"{name} (B2 = {row['B2']:g}, K2 = {row['K2']:g}; t_c = {row['t_c']:g} s, v = {row['v']:g} m/s): "
            f"{row['in_10000_any']:.0f} parcels in 10,000 break a constraint (95 % interval "
            f"{row['p_any_lo'] * 1e4:.0f}-{row['p_any_hi'] * 1e4:.0f}): {row['in_10000_overload']:.0f} hit too hard, "
            f"{row['in_10000_not_scraped']:.0f} not sorted; {row['decision']} p_max after {row['n']} parcels")


def summary_lines(df) -> list:
    """The run's summary: what it wrote, the least-risk element and each compared one."""
    run = df.attrs.get("run", {})
    lines = [f"wrote {run.get('out')}: {len(df)} elements x operating points, {run.get('cycles')} cycles in "
             f"{run.get('seconds', 0):.1f} s ({run.get('below')} below p_max, {run.get('above')} above, "
             f"{run.get('undecided')} undecided at the cap)"]
    if "B2" in df and "K2" in df:
        from fencesweep.report.risk_figures import least_risk

        lines.append(_line(least_risk(df).to_dict() | {"label": None}))
        lines += [_line(r) for r in df.to_dict("records") if isinstance(r["label"], str)]
    return lines


def cmd_risk(args: argparse.Namespace) -> int:
    from fencesweep.study import api

    if args.out is not None and not args.out.endswith(".parquet"):
        raise UsageError(f"--out {args.out!r} must end with .parquet")
    if args.jobs is not None and args.jobs < 1:
        raise UsageError(f"--jobs {args.jobs} is not allowed: --jobs must be >= 1")
    if args.backend == "dask" and not args.scheduler:
        raise UsageError("--backend dask needs --scheduler ADDRESS (e.g. tcp://HOST:8786)")
    try:
        df = api.risk(args.spec, out=args.out, jobs=args.jobs, resume=not args.no_resume, progress=not args.quiet,
                      backend=args.backend, scheduler=args.scheduler, overwrite=args.overwrite, wait=args.wait,
                      log=_say)
    except api.SweepInterrupted as exc:
        print(f"fencesweep: {exc.saved_text}; run the same command again to finish", file=sys.stderr)
        return 130
    except WriteError as exc:
        print(f"fencesweep: error: {exc}", file=sys.stderr)
        return 1
    if not args.quiet:
        print("\n".join(summary_lines(df)))
    return 0
