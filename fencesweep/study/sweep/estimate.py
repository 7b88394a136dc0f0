"""What a sweep would do, without doing it (`fencesweep grid --dry-run`, fencesweep.estimate).

The spec is planned (its scenes counted, resolved and deduplicated: the same checks as a real
run, so a bad spec fails here too), one run of each variant warms the engine up and a short
sample of runs spread over the sweep is timed; the estimate is the runs still to do (chunks
already saved in the work directory are counted as done) times the seconds per run, divided
by the local processes a real run would use. When the kernels are not compiled on this machine
yet, the warm-up compiles them, and the estimate includes that time (a first run pays it; the
dry run has paid it now). A spec swept in pieces (spec/pieces.py) is estimated from its first
piece, planned and timed as above, its counts and time scaled to the whole spec. Nothing is written.

`Estimate.lines()` is the text that `--dry-run` prints; `describe_plan` the plan's part of it,
which a real run also logs (skipped scenes, unused axes).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

from fencesweep.errors import UsageError
from fencesweep.kernel import cache
from fencesweep.study.spec import pieces as SP
from fencesweep.study.spec import spec as S
from fencesweep.study.sweep import output, runs
from fencesweep.study.sweep import plan as PL
from fencesweep.study.sweep import sample as VS
from fencesweep.study.sweep import verify as V
from fencesweep.study.sweep.progress import human

#: the kernel group (kernel/cache.py) that each scene's runs compile
KERNELS = {"cycle": "cycle", "stream": "cycle", "impact": "impact", "freefall": "impact"}


@dataclass
class Estimate:
    """A sweep's dry run: its plan, the engine's timing and the estimated time."""

    spec: str  # the spec's file ('spec' when it has none)
    scene: str
    out: Path
    n_scenes: int  # scenes to run (those that invalid: skip drops left out; all of them when not planned)
    shape: str  # the spec's dimensions, e.g. "2 cases x B2 81 x K2 81"
    n_models: int  # distinct model runs (of a spec in pieces: the first piece's, scaled)
    skipped: int = 0  # scenes dropped by invalid: skip
    skipped_example: str | None = None
    chunk_size: int | None = None  # runs per chunk (None: not known, the engine could not be timed)
    n_chunks: int | None = None
    unused_axes: list = field(default_factory=list)  # axes whose values all give the same run
    chunks_done: int = 0  # chunks an interrupted run already saved in `work`
    work: Path | None = None  # the work directory
    runs_left: int | None = None  # model runs still to do
    warm_up: float | None = None  # seconds the engine's warm-up took (loading the kernels)
    compiled: bool = False  # the warm-up compiled the kernels (they were not in the cache)
    per_run: float | None = None  # seconds per model run, timed on `timed_runs` runs
    timed_runs: int = 0
    jobs: int | None = None  # local processes a real run would use (None: a Dask cluster's workers)
    seconds: float | None = None  # estimated seconds on `jobs` (on Dask: of work in all), compiling included
    stop: str | None = None  # why a real run would stop before it starts (None: it would start)
    verify_runs: int | None = None  # runs the verification re-runs at most (None: no verification)
    verify_requested: bool = False  # --verify N (not the default sample)
    verify_seconds: float = 0.0  # estimated seconds of work of the verification (in `seconds`)
    unavailable: str | None = None  # why the time could not be estimated (the engine failed)
    pieces: int = 1  # pieces the spec is swept in (spec/pieces.py; >1: counts scaled from the first)

    @property
    def notes(self) -> list:
        """What a user should know besides the numbers."""
        out = [f"{axis} is not used by scene {self.scene}; its values all give the same run" for axis in self.unused_axes]
        if self.stop:
            out.append(f"a real run would stop before it starts: {self.stop}")
        if self.unavailable:
            out.append(f"estimated time unavailable: {self.unavailable}")
        return out

    def lines(self) -> list:
        """The dry run as `fencesweep grid --dry-run` prints it."""
        return [self.head()] + self.plan_lines() + self.time_lines()

    def head(self) -> str:
        """The first line: the spec, its scene, its scenes and the output."""
        return f"{self.spec}: scene {self.scene}, {self.n_scenes} scenes ({self.shape}) -> {self.out}"

    def plan_lines(self) -> list:
        """The plan: skipped scenes, distinct runs, chunks, unused axes."""
        lines = []
        if self.skipped:
            lines.append(f"  skipped (invalid: skip): {self.skipped} scenes, e.g. {self.skipped_example}")
        shared = self.n_scenes - self.n_models
        if self.pieces > 1:
            lines.append(f"  written in {self.pieces} pieces of up to {SP.piece_limit():,} scenes, a Parquet dataset "
                         f"of {self.pieces} parts; the counts below are the first piece's, scaled")
        about = "about " if self.pieces > 1 else ""
        lines.append(f"  distinct model runs: {about}{self.n_models}" + (f" ({shared} scenes share a run)" if shared else ""))
        if self.chunk_size:
            lines.append(f"  chunks: {self.n_chunks} of up to {self.chunk_size} runs")
        for axis in self.unused_axes:
            lines.append(f"  note: {axis} is not used by scene {self.scene}; its values all give the same run")
        return lines

    def time_lines(self) -> list:
        """Whether a real run would start, what is done, the engine's timing and the estimate."""
        if self.unavailable is not None:
            return [f"  estimated time: unavailable ({self.unavailable})"]
        lines = [f"  note: a real run would stop before it starts: {self.stop}"] if self.stop else []
        if self.chunks_done:
            lines.append(f"  already done: {self.chunks_done} chunks in {self.work}")
        compiled = " (compiling the kernels: first run on this machine)" if self.compiled else ""
        lines.append(f"  engine: warm-up {self.warm_up:.2f} s{compiled}; {self.per_run * 1e3:.3g} ms per run "
                     f"(timed on {self.timed_runs} runs)")
        split = (f" ({human(self.warm_up)} compiling, done now; {human(self.seconds - self.warm_up)} running)"
                 if self.compiled else "")
        lines.append(self.verify_line())
        runs = f"{self.runs_left} runs" + (f" and {self.verify_runs} re-runs" if self.verify_runs else "")
        if self.jobs:
            lines.append(f"  estimated time on {self.jobs} job{'s' if self.jobs > 1 else ''}: {human(self.seconds)} "
                         f"for {runs}{split}")
        else:
            lines.append(f"  estimated time: {human(self.seconds)} of work for {runs}, divided by "
                         f"the cluster's workers{split}")
        return lines


    def verify_line(self) -> str:
        """What the verification adds."""
        if self.verify_runs is None:
            return "  verification: none (--no-verify)"
        rule = "" if self.verify_requested else (f", at most {VS.COST_SHARE:.0%} of the run's steps beyond the "
                                                 f"first {VS.MIN_RUNS}")
        return (f"  verification: up to {self.verify_runs} of the {self.n_models} runs re-run at tol/10{rule} "
                f"(~{human(self.verify_seconds)} of work)")


def verify_seconds(n_models: int, n_verify: int, requested: bool, per_run: float) -> float:
    """Seconds of work of a verification of `n_verify` runs (the default sample: under its cost cap)."""
    if not requested:
        n_verify = min(n_verify, max(VS.MIN_RUNS, VS.COST_SHARE * n_models / VS.RERUN_COST))
    return n_verify * VS.RERUN_COST * per_run


def of_plan(plan: PL.Plan, out: Path) -> Estimate:
    """The plan's part of an estimate."""
    spec = plan.spec
    return Estimate(spec.path or "spec", spec.scene, out, plan.n_scenes - plan.skipped, spec.shape_text(),
                    plan.n_models, skipped=plan.skipped,
                    skipped_example=plan.skipped_examples[0] if plan.skipped else None,
                    chunk_size=plan.chunk_size, n_chunks=plan.n_chunks if plan.chunk_size else None,
                    unused_axes=PL.unused_axes(spec))


def describe_plan(plan: PL.Plan, out: Path) -> list:
    """The plan as the dry run shows it: its first line, then skipped scenes, runs, chunks, unused axes."""
    est = of_plan(plan, out)
    return [est.head()] + est.plan_lines()


def estimate(spec: S.Spec, out: Path, jobs: int, resume: bool = True, backend: str = "loky",
             overwrite: bool = False, progress: bool = False, simulate: Callable | None = None,
             verify: bool | int | None = None) -> Estimate:
    """Plan `spec` into `out`, time the engine on a sample and estimate the run on `jobs` local
    processes (backend loky) or a Dask cluster, the verification (`verify` as run_sweep takes
    it) included; write nothing. A spec in pieces is estimated from its first (_in_pieces). An
    engine that fails gives `unavailable`."""
    first, n_parts = next(SP.pieces(spec)), SP.n_pieces(spec)
    if n_parts > 1:
        return _in_pieces(spec, first, n_parts, out, jobs, backend, overwrite, simulate, verify)
    plan = PL.make_plan(spec)
    work = output.work_root(out) / plan.salt[:16]
    if plan.chunk_size is None and resume:
        plan.chunk_size = output.recorded_chunk_size(work)
    compiled = simulate is None and not cache.is_warm(KERNELS.get(spec.scene, "cycle"))
    try:
        t_warm = runs.warm_up(plan, simulate)
        per_run, k, _ = runs.time_sample(plan, simulate)
    except RuntimeError as exc:
        est = of_plan(plan, out)
        est.unavailable = str(exc)
        return est
    if plan.chunk_size is None:
        plan.chunk_size = runs.auto_chunk_size(plan.n_models, per_run)
    est = of_plan(plan, out)
    est.work, est.warm_up, est.per_run, est.timed_runs, est.compiled = work, t_warm, per_run, k, compiled
    if not overwrite:
        try:
            output.check_output(spec, out)
        except UsageError as exc:
            est.stop = str(exc)
    done = output.chunks_done(plan, work) if resume else []
    est.chunks_done = len(done)
    est.runs_left = plan.n_models - sum(len(plan.chunk_models(c)) for c in done)
    est.jobs = runs.local_jobs(jobs, per_run * est.runs_left) if backend != "dask" else None
    est.seconds = per_run * est.runs_left / (est.jobs or 1) + (t_warm if compiled else 0.0)
    if verify is not False:
        requested = verify is not None and verify is not True
        est.verify_runs = V.planned_runs(plan.n_models, int(verify) if requested else None)
        est.verify_requested = requested
        est.verify_seconds = verify_seconds(plan.n_models, est.verify_runs, requested, per_run)
        est.seconds += est.verify_seconds / (est.jobs or 1)
    return est


def _in_pieces(spec: S.Spec, first: S.Spec, n_parts: int, out: Path, jobs: int, backend: str, overwrite: bool,
               simulate: Callable | None, verify: bool | int | None) -> Estimate:
    """The estimate of a spec swept in pieces (spec/pieces.py): its first piece planned and
    timed as a whole spec is, the runs and the time scaled to the whole spec by its scenes."""
    est = estimate(first, out / "_estimate.parquet", jobs, False, backend, True, False, simulate, verify)
    scale = spec.n_scenes / first.n_scenes
    est.spec, est.out, est.shape, est.pieces = spec.path or "spec", out, spec.shape_text(), n_parts
    est.n_scenes, est.skipped = round(est.n_scenes * scale), round(est.skipped * scale)
    est.n_models = round(est.n_models * scale)
    est.n_chunks = None if est.n_chunks is None else round(est.n_chunks * scale)
    if est.seconds is not None:
        compiling = est.warm_up if est.compiled else 0.0
        est.runs_left, est.verify_seconds = round(est.runs_left * scale), est.verify_seconds * n_parts
        est.verify_runs = None if est.verify_runs is None else est.verify_runs * n_parts
        est.seconds = compiling + (est.seconds - compiling) * scale
    if not overwrite:
        try:
            output.check_output(spec, out)
        except UsageError as exc:
            est.stop = str(exc)
    return est
