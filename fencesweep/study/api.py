"""The Python API of the studies: one function per computing command of the CLI, named as its
verb and exported from `fencesweep` (README, Python API for sweeps). The CLI parses its
arguments, calls these and prints what they return.

* grid(spec, ...) runs a sweep (sweep.run_sweep) and returns its table as written, read back
  (store.read_table: attrs "units" and "fencesweep", the provenance), with attrs "run" (what
  the run did). An envelope spec also gets its per-design-point table (envelope.write_points),
  whose path is attrs "points_path" and which points(df) reads. run_grid is the same run
  without reading the table back (what `fencesweep grid` calls: a table may not fit in memory).
* estimate(spec, ...) is `fencesweep grid --dry-run`: an estimate.Estimate, nothing written.
* design(spec, ...) and sensitivity(spec, ...) run those studies (design.run_design,
  sensitivity.run) and return the recommendation (a dict) and the indices (a DataFrame).
* risk(spec, ...) runs a risk spec (spec/risk.py, risk/run.py) and returns its table, one row per
  element and operating point, with attrs "units", "fencesweep" and "run".

`spec` is a YAML file (its path), the parsed YAML of a spec (a dict) or a spec.Spec. Bad input
raises before anything is written: ParameterError (SpecError, a subclass, for a spec: it names
the key, the value and what is allowed) or UsageError. `log` receives the notes a user should see
(loads or scenes skipped, unused axes, resuming: what the CLI prints on stderr); by default
the "fencesweep" logger at level INFO. `progress`: True, False, or None (the default): a bar
when a person is watching (a terminal, a notebook), nothing otherwise (sweep/progress.py). Ctrl-C during a sweep raises SweepInterrupted (a KeyboardInterrupt): the chunks
finished are saved, and the same call again computes only the rest.
"""
from __future__ import annotations

import contextlib
import logging
import os
from pathlib import Path
from typing import Any, Callable

from fencesweep.errors import SweepInterrupted, SweepWriteError, UsageError, WorkerError, WriteError
from fencesweep.study.design import points as PT
from fencesweep.study.spec import envelope as E
from fencesweep.study.spec import file as specfile
from fencesweep.study.spec import spec as S
from fencesweep.study.store import lock
from fencesweep.study.store import table as store
from fencesweep.study.sweep import output
from fencesweep.study.sweep import pipeline as sweep
from fencesweep.study.sweep import verify as V
from fencesweep.study.sweep.estimate import Estimate
from fencesweep.study.sweep.estimate import estimate as _estimate
from fencesweep.study.sweep.progress import wanted as progress_wanted

__all__ = ["grid", "run_grid", "points", "estimate", "design", "sensitivity", "risk", "load_spec", "SweepInterrupted",
           "SweepWriteError"]

BACKENDS = ("loky", "dask", "cuda")



#: the default log: the notes go to the "fencesweep" logger (logging.getLogger("fencesweep")),
#: which the CLI shows on stderr and a library user routes or silences as any logger
_nothing = logging.getLogger("fencesweep.study").info


def load_spec(spec: Any) -> S.Spec:
    """A spec.Spec from a YAML file's path, the parsed YAML of a spec (a dict) or a Spec."""
    return _spec_from(spec, S.Spec, specfile.load, specfile.parse, "spec")


def _spec_from(spec: Any, cls: type, load: Callable, parse: Callable, what: str):
    """A `cls` from a YAML file's path (load), its parsed YAML (a dict: parse) or a `cls` itself;
    TypeError naming what is allowed otherwise."""
    if isinstance(spec, cls):
        return spec
    if isinstance(spec, (str, os.PathLike)):
        return load(spec)
    if isinstance(spec, dict):
        return parse(spec, source=_yaml_text(spec))
    raise TypeError(f"spec must be the path of a YAML {what}, a dict (its parsed YAML) or a "
                    f"{cls.__module__}.{cls.__name__}, not {type(spec).__name__}")


def _yaml_text(data: dict) -> str:
    """The spec's YAML, recorded as the table's spec_source (nothing if it cannot be written)."""
    import yaml

    try:
        return yaml.safe_dump(data, sort_keys=False)
    except yaml.YAMLError:
        return ""


def _check_jobs(jobs: Any, none_ok: bool = True) -> None:
    if jobs is None and none_ok:
        return
    if isinstance(jobs, bool) or not isinstance(jobs, int) or jobs < 1:
        raise UsageError(f"jobs = {jobs!r} is not allowed: jobs must be a whole number >= 1"
                         + (" (or None: all cores)" if none_ok else ""))


def _check_out(out: Any) -> None:
    if out is not None and not str(out).endswith(".parquet"):
        raise UsageError(f"out = {str(out)!r} must end with .parquet")


def _check_backend_name(backend: str, gpu: bool = True) -> None:
    allowed = BACKENDS if gpu else BACKENDS[:2]
    if backend not in allowed:
        raise UsageError(f"backend = {backend!r} is not allowed: 'loky' (processes on this machine), 'dask' "
                         f"(a Dask cluster, at scheduler = ADDRESS)" + (" or 'cuda' (a GPU of this machine, "
                                                                        "grid only)" if gpu else ""))


def _check_backend(backend: str, scheduler: str | None, gpu: bool = True) -> None:
    _check_backend_name(backend, gpu)
    if backend == "dask" and not scheduler:
        raise UsageError("backend = 'dask' needs scheduler = ADDRESS (e.g. 'tcp://HOST:8786')")
    if scheduler and backend != "dask":
        raise UsageError("scheduler is only used with backend = 'dask'")


def _dask_at(backend: str, scheduler: str | None) -> str | None:
    """The scheduler's address when the work goes to a Dask cluster (backend "dask"), else None."""
    return scheduler if backend == "dask" else None


def _note_skipped_loads(spec: S.Spec, log: Callable[[str], None]) -> None:
    if spec.envelope is not None and spec.envelope.skipped:
        log(f"note: {E._skip_text(spec.envelope, 'cannot start on the belt and are skipped (envelope.invalid: skip)')}")


def _out(spec: S.Spec, out: Any) -> Path:
    return Path(out) if out is not None else output.default_output(spec)


def grid(spec: Any, *, out: str | Path | None = None, jobs: int | None = None, resume: bool = True,
         progress: bool | None = None, backend: str = "loky", scheduler: str | None = None, overwrite: bool = False,
         verify: bool | int | None = None, wait: bool = False, adaptive: bool = False,
         log: Callable[[str], None] | None = None):
    """Run the sweep of `spec` into `out` (default: the spec's output) and return its table, read
    back from the Parquet file: row for row what `fencesweep grid` writes.

    `jobs`: local worker processes (None: all cores); `backend` "dask" runs on the cluster at
    `scheduler`. `resume`: reuse the chunks an interrupted run of the same spec saved. Without
    `overwrite`, another spec's table or unfinished run at `out` stops the sweep before it starts.
    `verify`: None, a sample of the runs is run again at tol / 10 and compared (sweep/verify.py); N:
    N runs; False: none. `wait`: wait for another run writing `out` instead of raising UsageError.
    df.attrs: "units" ({column: unit}), "fencesweep" (the provenance: spec, hash, versions,
    counts, "verify" the verification's record), "run" (run_grid's record) and, for a spec with
    an envelope, "points_path" (the per-design-point table: points(df) reads it).

    `adaptive`: an adaptive map instead of the full grid (adaptive/run.py; an envelope study or
    a grid with cases): the table has one row per cycle run, the points table (points(df)) every
    design point of the full grid with `sampled`; default out SPEC-output_adaptive.parquet."""
    run = run_grid(spec, out=out, jobs=jobs, resume=resume, progress=progress, backend=backend,
                   scheduler=scheduler, overwrite=overwrite, verify=verify, wait=wait, adaptive=adaptive, log=log)
    df = store.read_table(run["out"])
    df.attrs["run"] = run
    if run["points"] is not None:
        df.attrs["points_path"] = run["points"]["path"]
    return df


def _check_verify(verify: Any) -> None:
    if verify is None or isinstance(verify, bool):
        return
    if not isinstance(verify, int) or verify < 1:
        raise UsageError(f"verify = {verify!r} is not allowed: None (the default sample), a whole number >= 1 "
                         f"(runs to re-run) or False (no verification)")


def run_grid(spec: Any, *, out: str | Path | None = None, jobs: int | None = None, resume: bool = True,
             progress: bool | None = None, backend: str = "loky", scheduler: str | None = None, overwrite: bool = False,
             verify: bool | int | None = None, wait: bool = False, adaptive: bool = False,
             log: Callable[[str], None] | None = None) -> dict:
    """grid without reading the table back: run the sweep (and, for an envelope, write the
    per-design-point table) and return what the run did, a plain dict: out, scenes, model_runs,
    chunks, chunks_computed, chunks_reused, seconds, jobs (None: Dask), failed_runs (runs that
    raised in the engine: status 'failed: exception ...'), timings, verify (the verification's
    record, as in the table's metadata; None without one) and points (None, or for an envelope its
    path, design_points, loads, feasible, and the best point: min_margin, binding, best
    {column: value}). A failed verification also issues a verify.VerificationWarning. A file that
    cannot be written (a full disk) raises SweepWriteError (an OSError) saying what was kept.
    With `adaptive`, also "adaptive": the map's record (cycles run against the full grid's)."""
    log = log or _nothing
    progress = progress_wanted(progress)
    _check_out(out)
    _check_jobs(jobs)
    _check_backend(backend, scheduler)
    _check_verify(verify)
    sp = load_spec(spec)
    if backend == "cuda":
        sweep.gpu_device(sp)  # refused before anything is made: no numba-cuda, no GPU, another scene
    if adaptive:
        return _run_adaptive(sp, out, jobs, resume, backend, scheduler, progress, overwrite, verify, wait, log)
    out = _out(sp, out)
    _note_skipped_loads(sp, log)
    with _saying_what_is_saved(lambda: output.saved_chunks(sp, out)):
        output.check_writable(out)
        output.check_can_start(sp, out, overwrite)  # refused at once: not even the lock file is made
        with lock.one_writer(out, wait, log):  # the per-design-point table too
            res = sweep.run_sweep(sp, out, jobs=jobs, resume=resume, backend=backend, scheduler=scheduler,
                                  progress=progress, log=log, overwrite=overwrite, verify=verify, wait=wait)
            points = _write_points(sp, res.out) if sp.envelope is not None else None
    if res.verify is not None:
        V.warn(res.verify)
    return {"out": str(res.out), "scenes": res.n_scenes, "model_runs": res.n_models, "chunks": res.n_chunks,
            "chunks_computed": res.computed, "chunks_reused": res.reused, "seconds": res.seconds, "jobs": res.jobs,
            "failed_runs": res.failed_runs, "timings": dict(res.timings), "verify": res.verify, "points": points}


@contextlib.contextmanager
def _saying_what_is_saved(saved: Callable[[], tuple]):
    """Ctrl-C as SweepInterrupted, a failed write as SweepWriteError, each naming the chunks kept
    (`saved()`: work directory, chunks saved, chunks in all); a Dask worker without fencesweep
    (WorkerError) says them too."""
    try:
        yield
    except KeyboardInterrupt:
        raise SweepInterrupted(*saved()) from None
    except WriteError as exc:
        raise SweepWriteError(exc, *saved()) from None
    except WorkerError as exc:
        work, n, total = saved()
        kept = (f"the {n} chunk{'s' if n != 1 else ''} finished{f' (of {total})' if total else ''} "
                f"{'are' if n != 1 else 'is'} kept in {work}" if n else "no chunk was finished yet")
        raise WorkerError(f"{exc}; {kept}") from None


def _run_adaptive(sp: S.Spec, out, jobs, resume, backend, scheduler, progress, overwrite, verify, wait, log) -> dict:
    """run_grid of an adaptive map (adaptive_run.run_adaptive): the same record, and "adaptive"."""
    from fencesweep.study.adaptive import run as AR

    out = Path(out) if out is not None else AR.default_output(sp)
    _note_skipped_loads(sp, log)
    with _saying_what_is_saved(lambda: AR.saved_chunks(sp, out)):
        res = AR.run_adaptive(sp, out, jobs=jobs, resume=resume, backend=backend, scheduler=scheduler,
                              progress=progress, log=log, overwrite=overwrite, verify=verify, wait=wait)
    if res.verify is not None:
        V.warn(res.verify)
    cycles = res.record["cycles"]
    return {"out": str(res.out), "scenes": cycles, "model_runs": cycles,
            "chunks": res.chunks_computed + res.chunks_reused, "chunks_computed": res.chunks_computed,
            "chunks_reused": res.chunks_reused, "seconds": res.seconds, "jobs": res.jobs,
            "failed_runs": res.failed_runs, "timings": dict(res.timings), "verify": res.verify,
            "points": res.points, "adaptive": res.record}


def _plain(value: Any) -> Any:
    return value.item() if hasattr(value, "item") else value


def _write_points(spec: S.Spec, table: Path) -> dict:
    """Write an envelope sweep's per-design-point table; a summary of it."""
    path, pts = PT.write_points(spec, table)
    best = pts.loc[pts["min_margin"].idxmax()]
    return {"path": str(path), "design_points": len(pts), "loads": len(spec.envelope.loads),
            "feasible": int(pts["feasible"].sum()), "min_margin": float(best["min_margin"]),
            "binding": str(best["binding"]), "best": {c: _plain(best[c]) for c in PT.design_columns(spec)}}


def points(table: Any):
    """The per-design-point table of an envelope sweep (sweeps/README.md, Envelopes), as a
    DataFrame: of a table that grid returned (its attrs["points_path"]), or of the per-load
    table's path (OUT.parquet -> OUT_points.parquet)."""
    if isinstance(table, (str, os.PathLike)):
        path = PT.points_path(table)
    else:
        path = getattr(table, "attrs", {}).get("points_path")
        if path is None:
            raise UsageError("this table has no per-design-point table: grid writes one for a spec with an "
                             "envelope: section, and names it in df.attrs['points_path']")
    if not Path(path).exists():
        raise UsageError(f"{path} does not exist: grid writes it for a spec with an envelope: section")
    return store.read_table(path)


def estimate(spec: Any, *, out: str | Path | None = None, jobs: int | None = None, resume: bool = True,
             backend: str = "loky", overwrite: bool = False, progress: bool | None = None,
             verify: bool | int | None = None, log: Callable[[str], None] | None = None) -> Estimate:
    """What grid would do (`fencesweep grid --dry-run`), writing nothing: the scenes, distinct model
    runs and chunks, the chunks already done, the engine's warm-up and seconds per run, and the
    estimated time on `jobs` processes (None: all cores; backend "dask": work in all), with the
    runs the verification adds (`verify` as grid takes it: est.verify_runs). Its notes
    say what a user should know, e.g. that a real run would stop before it starts, and why;
    Estimate.lines() is the text the CLI prints."""
    import joblib

    log = log or _nothing
    progress = progress_wanted(progress)
    _check_out(out)
    _check_jobs(jobs)
    _check_backend_name(backend)
    _check_verify(verify)
    sp = load_spec(spec)
    _note_skipped_loads(sp, log)
    return _estimate(sp, _out(sp, out), jobs or joblib.cpu_count(), resume=resume, backend=backend,
                     overwrite=overwrite, progress=progress, verify=verify)


def design(spec: Any, *, out: str | Path | None = None, jobs: int = 1, progress: bool | None = None,
           backend: str = "loky", scheduler: str | None = None, log: Callable[[str], None] | None = None) -> dict:
    """`fencesweep design`: search the spec's design variables for the element farthest inside
    every constraint for every load of its envelope, verify it on a fresh sample and write
    OUT/recommended.json, comparison.parquet and verify_loads.parquet (OUT: default the design
    section's output). Returns the recommendation (recommended.json's content). The search judges
    its points on `jobs` local processes, or with backend "dask" on the cluster at `scheduler`: the
    same result either way."""
    from fencesweep.study.design import search as D

    log = log or _nothing
    progress = progress_wanted(progress)
    _check_jobs(jobs, none_ok=False)
    _check_backend(backend, scheduler, gpu=False)
    sp = load_spec(spec)
    if sp.design is None:
        raise UsageError(f"{sp.path or 'the spec'} has no design: section (variables, constraints, objective); see "
                         f"sweeps/envelope.yaml")
    _note_skipped_loads(sp, log)
    return D.run_design(sp, jobs=jobs, progress=progress, out_dir=out, log=log, scheduler=_dask_at(backend, scheduler))


def sensitivity(spec: Any, *, out: str | Path | None = None, jobs: int | None = None, progress: bool | None = None,
                backend: str = "loky", scheduler: str | None = None, log: Callable[[str], None] | None = None):
    """`fencesweep sensitivity`: the Sobol indices (S1, ST) of the spec's sensitivity: outputs to its
    assumed inputs; runs the sample as a sweep (OUT_runs.parquet, OUT_runs_points.parquet; on
    `jobs` local processes, or with backend "dask" on the cluster at `scheduler`) and writes the
    indices to OUT (default: the section's output). Returns them as a DataFrame."""
    from fencesweep.study.design import sensitivity as SA

    _check_jobs(jobs)
    _check_out(out)
    _check_backend(backend, scheduler, gpu=False)
    sp = load_spec(spec)
    if sp.sensitivity is None:
        raise UsageError(f"{sp.path or 'the spec'} has no sensitivity: section; see sweeps/sensitivity.yaml")
    return SA.run(sp, jobs=jobs, progress=progress_wanted(progress), out=out, log=log or _nothing,
                  backend=backend, scheduler=scheduler)


def _load_risk_spec(spec: Any):
    from fencesweep.study.spec import risk as RS

    return _spec_from(spec, RS.RiskSpec, RS.load, RS.parse, "risk spec")


def _check_risk_output(sp, out: Path, overwrite: bool) -> None:
    """Refuse (UsageError) to replace a table at `out` that is not this risk spec's (or not a table),
    or to discard another risk spec's unfinished run saved beside it."""
    import json

    if overwrite:
        return
    for state in sorted(Path(str(out) + ".partial").glob("*/risk.json")):
        try:
            other = json.loads(state.read_text()).get("spec_hash")
        except (OSError, ValueError):
            continue
        if other != sp.hash and any(state.parent.glob("chunk-*.parquet")):
            raise UsageError(f"{state.parent.parent} holds the unfinished run of another risk spec; not discarding it: "
                             f"finish that run first, choose another --out, or add --overwrite to discard it")
    if not out.exists():
        return
    try:
        meta = store.read_metadata(out)
    except (OSError, ValueError):
        meta = {}
    if meta.get("spec_hash") != sp.hash or "risk" not in meta:
        raise UsageError(f"{out} exists and is not a table of this risk spec; not replacing it: choose another "
                         f"--out, or add --overwrite to replace it")


def risk(spec: Any, *, out: str | Path | None = None, jobs: int | None = None, resume: bool = True,
         progress: bool | None = None, backend: str = "loky", scheduler: str | None = None, overwrite: bool = False,
         wait: bool = False, log: Callable[[str], None] | None = None, simulate: Callable | None = None):
    """`fencesweep risk`: per element and operating point of the risk spec, the probabilities that a
    parcel of its population breaks each constraint and any (sweeps/README.md, Risk from a parcel
    mix), sampled round by round until the P(any) interval is wholly below or above p_max or the
    cap is reached; written to `out` (default: the spec's output) and returned as a DataFrame,
    one row per element and operating point: df.attrs "units", "fencesweep" (provenance: the
    spec, the population, the interval), "run" (cycles, chunks, seconds). The flags are grid's;
    Ctrl-C keeps the rounds' finished chunks, and the same call again runs only the rest."""
    from fencesweep.study.risk import run as RR

    log = log or _nothing
    progress = progress_wanted(progress)
    _check_out(out)
    _check_jobs(jobs)
    _check_backend(backend, scheduler, gpu=False)
    sp = _load_risk_spec(spec)
    out = Path(out) if out is not None else Path(sp.output or f"{Path(sp.path).stem if sp.path else 'risk'}.parquet")
    if sp.population.left_out:
        log(f"note: {len(sp.population.left_out)} of {sp.population.n_file} parcels of {sp.population.source} are "
            f"wider than the belt and are left out (population.too_large: skip), e.g. row "
            f"{sp.population.left_out[0]}")
    if jobs is None:
        import joblib

        jobs = joblib.cpu_count()
    with _saying_what_is_saved(lambda: RR.saved_chunks(sp, out)):
        output.check_writable(out)
        _check_risk_output(sp, out, overwrite)
        with lock.one_writer(out, wait, log):
            record = RR.run_risk(sp, out, jobs, resume=resume, local=backend != "dask", scheduler=scheduler,
                                 progress=progress, log=log, simulate=simulate)
    df = store.read_table(out)
    df.attrs["run"] = record | {"rounds": [list(map(int, r)) for r in record["rounds"]]}
    return df
