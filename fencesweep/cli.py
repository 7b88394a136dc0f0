"""The command line: `fencesweep run | grid | design | sensitivity | risk | plot | plot-design`. No
physics and no orchestration here: each command parses its arguments, calls the Python API
(fencesweep.model.simulate for one scene, fencesweep.study.api for the studies) and prints.
`run` is in run_cli.py and `risk` in risk_cli.py; this module registers them.

Bad input prints one clear message (the parameter, the value, what is allowed) and exits
with code 2; nothing runs then.
"""
from __future__ import annotations

import argparse
import atexit
import contextlib
import gc
import logging
import math
import sys
import warnings
from pathlib import Path

from fencesweep.errors import MissingInput, MissingTable, UsageError, VerificationWarning, WorkerError, WriteError
from fencesweep.model import params as P
from fencesweep.study import api
from fencesweep.version import __version__

__all__ = ["main", "build_parser", "UsageError"]


def add_grid_parser(sub) -> argparse.ArgumentParser:
    g = sub.add_parser(
        "grid", help="run a parameter sweep from a YAML spec into one Parquet table",
        description="Run every scene of a sweep spec (sweeps/README.md) on all cores and write one "
                    "Parquet table, one row per scene. A killed sweep, rerun, computes only what is missing.")
    g.add_argument("spec", metavar="SPEC.yaml", help="the sweep spec (see sweeps/README.md)")
    g.add_argument("--out", metavar="PATH.parquet", help="output table (default: the spec's output)")
    g.add_argument("--jobs", type=int, default=None, metavar="N", help="worker processes (default: all cores)")
    g.add_argument("--dry-run", action="store_true",
                   help="print the scene count, model runs and an estimated time; run nothing else")
    g.add_argument("--no-resume", action="store_true", help="discard chunks of an interrupted run")
    g.add_argument("--overwrite", action="store_true",
                   help="replace a table (or discard the unfinished run) that another spec left at the output")
    add_backend_args(g, gpu=True)
    check = g.add_mutually_exclusive_group()
    check.add_argument("--verify", type=int, default=None, metavar="N",
                       help="re-run N of the runs at a 10x tighter tolerance and record how the table differs "
                            "(default: max(16, 1%%) of them, the extremes first, at most ~5%% of the run's cost)")
    check.add_argument("--no-verify", action="store_true", help="no verification")
    g.add_argument("--wait", action="store_true",
                   help="if another run is writing the same output, wait for it (default: refuse at once)")
    g.add_argument("--adaptive", action="store_true",
                   help="an envelope study or a grid with cases: simulate the design points where the verdict "
                        "changes, infer the rest (sweeps/README.md, Adaptive maps); writes SPEC-output_adaptive.parquet")
    g.add_argument("--quiet", action="store_true", help="no progress bar and no summary (warnings are still shown)")
    g.set_defaults(func=cmd_grid)
    return g


def add_backend_args(parser: argparse.ArgumentParser, gpu: bool = False) -> None:
    """--backend and --scheduler (grid, design, sensitivity; checked by _check_backend_args); with
    `gpu` (grid) also --backend cuda."""
    parser.add_argument("--backend", choices=("loky", "dask", "cuda") if gpu else ("loky", "dask"), default="loky",
                        help="loky: processes on this machine; dask: a Dask cluster (needs --scheduler)"
                             + ("; cuda: one GPU thread per cycle (cycle scenes; pip install -e \".[gpu]\")"
                                if gpu else ""))
    parser.add_argument("--scheduler", metavar="ADDRESS", help="Dask scheduler, e.g. tcp://HOST:8786")


def _check_backend_args(args: argparse.Namespace) -> None:
    if args.backend == "dask" and not args.scheduler:
        raise UsageError("--backend dask needs --scheduler ADDRESS (e.g. tcp://HOST:8786)")
    if args.scheduler and args.backend != "dask":
        raise UsageError("--scheduler is only used with --backend dask")


#: the package's logger: notes, summaries and the compile notice; main() shows it on stderr
LOG = logging.getLogger("fencesweep")


def _say(args: argparse.Namespace):
    """The notes and summaries, through the "fencesweep" logger (a warning at WARNING, the rest at
    INFO: with --quiet only the warnings show)."""
    def say(msg: str) -> None:
        (LOG.warning if msg.startswith("warning") else LOG.info)(msg)

    return say


@contextlib.contextmanager
def _messages(quiet: bool):
    """The "fencesweep" logger shown on stderr, message only, for the length of a command (INFO;
    WARNING with --quiet); the logger's own settings are put back afterwards."""
    handler = logging.StreamHandler(sys.stderr)
    handler.setFormatter(logging.Formatter("%(message)s"))
    level, propagate = LOG.level, LOG.propagate
    LOG.addHandler(handler)
    LOG.setLevel(logging.WARNING if quiet else logging.INFO)
    LOG.propagate = False
    try:
        yield
    finally:
        handler.flush()
        LOG.removeHandler(handler)
        LOG.setLevel(level)
        LOG.propagate = propagate


def _verify_arg(args: argparse.Namespace):
    """--verify N / --no-verify as the API's verify: N, False or None (the default sample)."""
    if args.no_verify:
        return False
    if args.verify is not None and args.verify < 1:
        raise UsageError(f"--verify {args.verify} is not allowed: --verify N re-runs N >= 1 runs (--no-verify: none)")
    return args.verify


def cmd_grid(args: argparse.Namespace) -> int:
    if args.out is not None and not args.out.endswith(".parquet"):
        raise UsageError(f"--out {args.out!r} must end with .parquet")
    if args.jobs is not None and args.jobs < 1:
        raise UsageError(f"--jobs {args.jobs} is not allowed: --jobs must be >= 1")
    _check_backend_args(args)
    say = _say(args)
    verify = _verify_arg(args)
    if args.dry_run:
        est = api.estimate(args.spec, out=args.out, jobs=args.jobs, resume=not args.no_resume, backend=args.backend,
                           overwrite=args.overwrite, progress=not args.quiet, verify=verify, log=say)
        print("\n".join(est.lines()))
        if args.backend == "cuda":
            print("--backend cuda: the times above are this machine's CPU's; the GPU's are not estimated")
        if args.adaptive:
            print("--adaptive runs a part of these, known only as the map refines (sweeps/README.md, Adaptive maps): "
                  "the estimate above is the full grid's, an upper bound")
        return 0
    try:
        with warnings.catch_warnings():  # a failed verification's warning: printed below, as lines
            warnings.simplefilter("ignore", verify_warning())
            run = api.run_grid(args.spec, out=args.out, jobs=args.jobs, resume=not args.no_resume,
                               backend=args.backend, scheduler=args.scheduler, progress=not args.quiet,
                               overwrite=args.overwrite, verify=verify, wait=args.wait, adaptive=args.adaptive,
                               log=say)
    except api.SweepInterrupted as exc:
        print(f"fencesweep: {exc.saved_text}; run the same command again to finish", file=sys.stderr)
        return 130
    except WriteError as exc:  # a full disk: what was kept, and what to do
        print(f"fencesweep: error: {exc}", file=sys.stderr)
        return 1
    _grid_summary(run, say)
    return 0


def verify_warning() -> type:
    return VerificationWarning


def _grid_summary(run: dict, say) -> None:
    """What a finished sweep wrote, its verification and its warnings."""
    from fencesweep.study.sweep import verify as V

    rate = run["scenes"] / run["seconds"] if run["seconds"] > 0 else math.inf
    where = "Dask" if run["jobs"] is None else f"{run['jobs']} job{'s' if run['jobs'] != 1 else ''}"
    say(f"wrote {run['out']}: {run['scenes']} scenes ({run['model_runs']} model runs; {run['chunks_computed']} chunks "
        f"computed, {run['chunks_reused']} reused) in {run['seconds']:.1f} s, {rate:.1f} scenes/s on {where}")
    if run["verify"] is not None:
        say(V.summary_line(run["verify"]))
        for line in V.warning_lines(run["verify"]):
            say(line)
    if run["failed_runs"]:
        say(f"warning: {run['failed_runs']} scenes raised in the engine; their status is 'failed: exception ...'")
    if run["points"] is not None:
        say(_points_line(run["points"]))
    if run.get("adaptive") is not None:
        say(_adaptive_line(run["adaptive"]))


def _points_line(pts: dict) -> str:
    """An envelope sweep's per-design-point table in one line: its size, the feasible points, the best one."""
    label = ", ".join(f"{c} = {v:g}" if isinstance(v, float) else f"{c} = {v}" for c, v in pts["best"].items())
    kept = ("are ok (scraped, overload <= 1, deflection within the limit)" if pts.get("verdict") == "ok"
            else "keep every constraint for every load")
    return (f"wrote {pts['path']}: {pts['design_points']} design points x {pts['loads']} loads; "
            f"{pts['feasible']} {kept}; largest smallest margin {pts['min_margin']:.3f}"
            + (f" at {label}" if label else "") + f" (binding: {pts['binding']})")


def _adaptive_line(rec: dict) -> str:
    """An adaptive map's cost against the full grid's, and what was inferred."""
    from fencesweep.study.adaptive.run import per_cycle_note

    return (f"adaptive map: {per_cycle_note(rec)}; {rec['simulated']} of {rec['design_points']} design points "
            f"simulated, {rec['inferred']} inferred (the points table's `sampled` column says which)")


def add_design_parser(sub) -> argparse.ArgumentParser:
    d = sub.add_parser(
        "design", help="find the element that keeps every constraint for every load of an envelope",
        description="Search the design variables of a spec's design: section (differential evolution, seeded) "
                    "judging each point over the spec's envelope of loads; verify the optimum on a fresh, denser "
                    "sample; compare it with the paper's and other elements. Writes DIR/recommended.json, "
                    "DIR/comparison.parquet and DIR/verify_loads.parquet (sweeps/README.md, Envelopes).")
    d.add_argument("spec", metavar="SPEC.yaml", help="a spec with envelope: and design: sections")
    d.add_argument("--out", metavar="DIR", help="output directory (default: the design section's output)")
    d.add_argument("--jobs", type=int, default=1, metavar="N", help="worker processes (default 1)")
    add_backend_args(d)
    d.add_argument("--quiet", action="store_true", help="no progress bar and no summary")
    d.set_defaults(func=cmd_design)
    return d


def cmd_design(args: argparse.Namespace) -> int:
    from fencesweep.study.design.search import summary_lines

    if args.jobs < 1:
        raise UsageError(f"--jobs {args.jobs} is not allowed: --jobs must be >= 1")
    _check_backend_args(args)
    rec = api.design(args.spec, out=args.out, jobs=args.jobs, progress=not args.quiet, backend=args.backend,
                     scheduler=args.scheduler, log=_say(args))
    if not args.quiet:
        print("\n".join(summary_lines(rec)))
    return 0


def add_sensitivity_parser(sub) -> argparse.ArgumentParser:
    g = sub.add_parser("sensitivity", help="Sobol indices of an element's worst results to the assumed inputs",
                       description="Run a spec's sensitivity: section (Saltelli sample of the assumed inputs crossed "
                                   "with its envelope, as a sweep) and write the Sobol indices S1 and ST (SALib: "
                                   "pip install 'fencesweep[sensitivity]').")
    g.add_argument("spec", metavar="SPEC.yaml", help="a spec with envelope: and sensitivity: sections")
    g.add_argument("--out", metavar="PATH.parquet", help="the indices table (default: the section's output)")
    g.add_argument("--jobs", type=int, default=None, metavar="N", help="worker processes (default: all cores)")
    add_backend_args(g)
    g.add_argument("--quiet", action="store_true", help="no progress bar and no summary")
    g.set_defaults(func=cmd_sensitivity)
    return g


def cmd_sensitivity(args: argparse.Namespace) -> int:
    from fencesweep.study.design.sensitivity import summary_lines

    if args.jobs is not None and args.jobs < 1:
        raise UsageError(f"--jobs {args.jobs} is not allowed: --jobs must be >= 1")
    if args.out is not None and not args.out.endswith(".parquet"):
        raise UsageError(f"--out {args.out!r} must end with .parquet")
    _check_backend_args(args)
    df = api.sensitivity(args.spec, out=args.out, jobs=args.jobs, progress=not args.quiet, backend=args.backend,
                         scheduler=args.scheduler, log=_say(args))
    if not args.quiet:
        print("\n".join(summary_lines(df)))
    return 0


def add_plot_design_parser(sub) -> argparse.ArgumentParser:
    from fencesweep.report.design_figures import FIGURES

    what = list(FIGURES) + ["all"]
    g = sub.add_parser("plot-design", help="draw the design figures (envelope map, loads, window, sensitivity, risk map)",
                       description="Draw the figures of the design for every package into RESULTS/figures/ from "
                                   "the tables of fencesweep grid sweeps/envelope.yaml and fencesweep design "
                                   "(needs matplotlib). Figures: " + ", ".join(FIGURES))
    g.add_argument("what", nargs="*", default=[], metavar="NAME",
                   help=f"one or more of: {', '.join(what)} (default: all)")
    g.add_argument("--results", default="results", metavar="DIR", help="directory of the tables (default: results)")
    g.add_argument("--out", default=None, metavar="DIR", help="where the PNGs go (default: RESULTS/figures)")
    g.set_defaults(func=cmd_plot_design)
    return g


def cmd_plot_design(args: argparse.Namespace) -> int:
    from fencesweep.report.design_figures import FIGURES, plot

    bad = [w for w in args.what if w not in FIGURES and w != "all"]
    if bad:
        raise UsageError(f"plot-design {bad[0]!r}: no such figure (one of {', '.join(FIGURES)}, all)")
    try:
        for p in plot(args.what, Path(args.results), args.out, log=lambda m: print(m, file=sys.stderr)):
            print(p)
    except MissingTable as exc:
        raise UsageError(str(exc)) from None
    return 0


def add_plot_parser(sub) -> argparse.ArgumentParser:
    """Register `fencesweep plot` on the CLI's subparsers."""
    from fencesweep.report import analysis as A
    from fencesweep.report import figures as F

    what = list(F.FIGURES) + ["all", "trajectories", "report"]
    g = sub.add_parser(
        "plot", help="draw the paper's figures and the design maps (PNG) from the results tables",
        description="Draw figures into RESULTS/figures/ from the sweep tables and trajectories in RESULTS "
                    "(needs matplotlib: pip install 'fencesweep[plot]'). 'trajectories' runs the single cycles "
                    "the figures need; 'report' writes RESULTS/REPORT.md. Figures: "
                    + "; ".join(f"{k}: {v[1]}" for k, v in F.FIGURES.items()))
    g.add_argument("what", nargs="*", default=["all"], choices=what, metavar="NAME",
                   help=f"one or more of: {', '.join(what)} (default: all)")
    g.add_argument("--results", default="results", metavar="DIR",
                   help="directory of the tables and trajectories (default: results)")
    g.add_argument("--out", default=None, metavar="DIR", help="where the PNGs go (default: RESULTS/figures)")
    g.add_argument("--residual-max", type=float, default=A.RESIDUAL_MAX_DEG, metavar="DEG",
                   help=f"residual amplitude [deg] under which the fence counts as home for the next cycle "
                        f"(design maps, report; default {A.RESIDUAL_MAX_DEG:g})")
    g.set_defaults(func=cmd_plot)
    return g


def cmd_plot(args: argparse.Namespace) -> int:
    from fencesweep.report import analysis as A
    from fencesweep.report import document
    from fencesweep.report import figures as F

    res = Path(args.results)
    what = args.what or ["all"]
    try:
        if "trajectories" in what:
            A.make_trajectories(res, residual_max_deg=args.residual_max)
            what = [w for w in what if w != "trajectories"]
            if not what:
                return 0
        report = "report" in what
        what = [w for w in what if w != "report"]
        if what:
            for p in F.plot(what, res, args.out, args.residual_max):
                print(p)
        if report:
            print(document.write_report(res, args.residual_max))
    except MissingInput as exc:
        print(f"fencesweep: error: {exc}", file=sys.stderr)
        return 2
    except ImportError as exc:
        print(f"fencesweep: error: {exc}; install the plotting extra: pip install 'fencesweep[plot]'", file=sys.stderr)
        return 2
    return 0


def build_parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(prog="fencesweep", description="Active rotary fence: one cycle, or sweeps of many.")
    ap.add_argument("--version", action="version", version=f"fencesweep {__version__}")
    sub = ap.add_subparsers(dest="command", required=True)

    from fencesweep.run_cli import add_run_parser

    add_run_parser(sub)

    add_grid_parser(sub)
    add_design_parser(sub)
    add_sensitivity_parser(sub)
    from fencesweep.risk_cli import add_risk_parser

    add_risk_parser(sub)
    add_plot_design_parser(sub)
    add_plot_parser(sub)
    from fencesweep.gpuinfo import add_gpu_info_parser

    add_gpu_info_parser(sub)
    return ap


def main(argv: list[str] | None = None) -> int:
    # at exit, the collector's last passes over the engine's objects (numba, llvmlite, pyarrow,
    # pandas) took 0.2-0.3 s of every command; frozen, they are skipped (nothing is left open then)
    atexit.unregister(gc.freeze)
    atexit.register(gc.freeze)
    ap = build_parser()
    args = ap.parse_args(argv)
    try:
        with _messages(getattr(args, "quiet", False)):
            return int(args.func(args) or 0)
    except (P.ParameterError, UsageError) as exc:
        print(f"fencesweep: error: {exc}", file=sys.stderr)
        return 2
    except WorkerError as exc:  # a Dask worker without fencesweep: named; the chunks finished are kept
        print(f"fencesweep: error: {exc}", file=sys.stderr)
        return 1


if __name__ == "__main__":
    sys.exit(main())
