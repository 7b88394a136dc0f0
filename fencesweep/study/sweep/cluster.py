"""The `dask` backend: a study's work on a Dask cluster (docs/dask.md), from one place.

* connect(scheduler, warm): a Client of the scheduler at `scheduler` for a with-block; with
  `warm`, the workers are warmed up first. results(client, calls) runs a sweep's chunks and its
  verification's re-runs there (sweep/compute.py), as they finish, the first given first, never
  more in flight than twice the cluster's threads (at least 2), so that results do not pile up;
  the sweep's spec and engine go to each worker once. It waits for workers that have not
  started yet (a batch system's queue), and a cluster of one thread runs the tasks on that
  thread (joblib's dask backend, used before, ran them in the client then, and gave up after
  10 s without a worker).
* warm_up(client, spec, rows): every worker, now and any that joins later, warms up once, before
  its first task: a distributed.WorkerPlugin (PLUGIN) whose setup imports fencesweep there,
  checks that it is the client's (its version and kernel sources: another engine would write
  other numbers under this sweep's name) and runs the scenes `rows` (runs.warm_scenes), which
  compiles the kernels into the worker's Numba cache or, with a NUMBA_CACHE_DIR the workers
  share, loads them. The plugin's class is made by a function (_plugin_class), so its code
  travels by value (cloudpickle): it reaches a worker without fencesweep and says so from there.
  Registering it again (the next sweep) replaces it; a warm worker then only runs the scenes.
* time_sample(scheduler, plan): what runs.warm_up and runs.time_sample give, measured on the
  cluster: the client compiles nothing that only the workers run.
* mapper(scheduler, fn, shared): a map over the workers for scipy's `workers=` (the design's
  optimiser), in order, so that its result is the local one.

A worker that cannot import fencesweep raises WorkerError naming its address: from the plugin's
setup, or, for one that joined after the warm-up and failed a task, from a probe of every worker
(missing). The chunks written until then are kept.
"""
from __future__ import annotations

import contextlib
import functools
import itertools
import logging
import time
from typing import Callable, Iterable, Iterator

import numpy as np

from fencesweep.errors import UsageError, WorkerError
from fencesweep.model import params as P
from fencesweep.study.spec import spec as S
from fencesweep.study.sweep import runs

#: the package every worker must import, and the name the warm-up is registered under
PACKAGE = __name__.split(".")[0]
PLUGIN = f"{PACKAGE}-warm-up"
_ADVICE = f"every Dask worker needs the same {PACKAGE} installed as this client (docs/dask.md)"
#: notes for the user (the CLI shows the "fencesweep" logger's INFO on stderr)
_log = logging.getLogger(__name__)


@contextlib.contextmanager
def connect(scheduler: str | None, warm: tuple | None = None) -> Iterator:
    """A Client of the scheduler at `scheduler` for a with-block; with `warm` = (spec, rows,
    simulate), the workers warmed up first (warm_up). A task that fails because fencesweep cannot
    be imported on its worker raises WorkerError."""
    try:
        from dask.distributed import Client
    except ImportError as exc:
        raise UsageError(f"--backend dask needs dask.distributed ({exc}); install it with "
                         f"pip install 'fencesweep[dask]'") from None
    try:
        client = Client(scheduler, timeout="20s")
    except (OSError, TimeoutError) as exc:
        raise UsageError(f"--scheduler {scheduler!r}: cannot reach the Dask scheduler ({exc})") from None
    with client:
        try:
            if warm is not None:
                warm_up(client, *warm)
            yield client
        except WorkerError:
            raise
        except Exception as exc:  # a task that cannot be unpickled on a worker raises Exception(its error's repr)
            if not _is_ours(exc):
                raise
            raise WorkerError(_missing_text(missing(client)) or f"a Dask worker cannot import {PACKAGE} ({exc}): "
                              f"{_ADVICE}") from None


def results(client, calls: Iterable[tuple], shared=None) -> Iterator:
    """The results of calls (fn, *args) on the workers of `client`'s cluster, as they finish
    (module docstring). A call whose last argument is `shared` (the sweep's spec and engine) gets
    it from the workers' memory: it is sent there once, not with each task."""
    from distributed import as_completed

    calls, held = iter(calls), []

    def submit(call: tuple):
        fn, *args = call
        if shared is not None and args and args[-1] is shared:
            if not held:
                held.append(_send(client, shared))
            args[-1] = held[0]
        return client.submit(fn, *args, pure=False)

    def room(running: int) -> int:
        return max(2, 2 * sum(client.nthreads().values())) - running

    running = as_completed([submit(call) for call in itertools.islice(calls, room(0))])
    for done in running:
        result = done.result()
        del done  # the worker may forget it
        for call in itertools.islice(calls, max(room(running.count()), 0)):
            running.add(submit(call))
        yield result


def _send(client, shared):
    """`shared` in the memory of every worker of `client`'s cluster, once (its Future), after
    waiting for the first worker if there is none yet (a batch system's queue)."""
    if not client.nthreads():
        _log.info(f"waiting for the first Dask worker to join {client.scheduler.address}")
        client.wait_for_workers(1)
    [held] = client.scatter([shared], broadcast=True, hash=False)
    return held


def _is_ours(exc: Exception) -> bool:
    """Is `exc` a worker's failure to import fencesweep?"""
    if isinstance(exc, ImportError) and exc.name is not None:
        return exc.name.split(".")[0] == PACKAGE
    return f"No module named '{PACKAGE}" in str(exc)


def _missing_text(found: dict) -> str:
    """What WorkerError says of the workers `found` ({address: why}) that cannot import fencesweep."""
    if len(found) == 1:
        [(address, why)] = found.items()
        return f"the Dask worker {address} cannot import {PACKAGE} ({why}): {_ADVICE}"
    names = ", ".join(f"{address} ({why})" for address, why in sorted(found.items()))
    return f"the Dask workers {names} cannot import {PACKAGE}: {_ADVICE}" if found else ""


def identity() -> dict:
    """This process's fencesweep: its version and the digest of its kernel sources."""
    from fencesweep.kernel import cache
    from fencesweep.version import __version__

    return {"version": __version__, "kernels": cache.HASH[:12]}


def warm_up(client, spec: S.Spec, rows: list, simulate: Callable | None = None) -> float:
    """Warm every worker of `client`'s cluster up (module docstring), and any that joins later:
    check its fencesweep and run the scenes `rows` of `spec` there. Returns the seconds this
    process waited (the workers warm up in parallel). A worker that cannot import fencesweep,
    or runs another version of it, raises WorkerError naming it."""
    import cloudpickle

    plugin = _plugin_class()(cloudpickle.dumps((spec, [int(r) for r in rows], simulate)), identity())
    t0 = time.perf_counter()
    try:
        client.register_plugin(plugin, name=PLUGIN)
    except ImportError as exc:  # the plugin's setup on a worker without fencesweep: it names the worker
        raise WorkerError(f"{exc}: {_ADVICE}") from None
    return time.perf_counter() - t0


def warm_worker(payload: bytes, expected: dict, address: str) -> float:
    """On a worker, the warm-up's work (the plugin's setup): check that its fencesweep is the
    client's `expected` (identity), then run the payload's scenes; the seconds the scenes took."""
    import pickle

    found = identity()
    if found != expected:
        raise WorkerError(f"the Dask worker {address} runs {PACKAGE} {found['version']} (kernel sources "
                          f"{found['kernels']}), this client {expected['version']} (kernel sources "
                          f"{expected['kernels']}): {_ADVICE}")
    spec, rows, simulate = pickle.loads(payload)
    return runs.warm_scenes(spec, rows, simulate)


@functools.cache
def _plugin_class() -> type:
    """The warm-up's WorkerPlugin class. Made here, in a function, so that cloudpickle sends its
    code with it: its setup runs on a worker that lacks fencesweep and names that worker. It may
    use nothing of this module but the names it imports there."""
    from distributed import WorkerPlugin

    class WarmUp(WorkerPlugin):
        """Imports fencesweep on the worker and runs warm_worker there, off the worker's event loop;
        `seconds`: how long the scenes took on this worker (None until set up)."""

        module = __name__

        def __init__(self, payload: bytes, expected: dict):
            self.payload, self.expected, self.seconds = payload, expected, None

        async def setup(self, worker):
            import asyncio
            import importlib

            try:
                here = importlib.import_module(self.module)
            except ImportError as exc:
                package = self.module.split(".")[0]
                raise ImportError(f"the Dask worker {worker.address} cannot import {package} ({exc})") from None
            self.seconds = await asyncio.get_running_loop().run_in_executor(
                None, here.warm_worker, self.payload, self.expected, worker.address)

    return WarmUp


def missing(client) -> dict:
    """{address: why} of the workers of `client`'s cluster that cannot import fencesweep."""
    found = client.run(_importer(), PACKAGE)
    return {address: why for address, why in found.items() if why is not None}


def _importer() -> Callable:
    """A function that tries to import a package on a worker: None, or why it cannot. Made here,
    in a function, so that cloudpickle sends its code (the worker need not have this module)."""
    def can_import(package: str):
        import importlib

        try:
            importlib.import_module(package)
        except ImportError as exc:
            return str(exc)
        return None

    return can_import


def first_rows(spec: S.Spec, most: int = 100) -> list:
    """The first scene of `spec` that resolves (among its first `most`), as a list: the rows a
    study without a plan warms its workers up with."""
    for i in range(min(spec.n_scenes, most)):
        try:
            spec.resolve(i)
        except P.ParameterError:
            continue
        return [i]
    return []


class _Rows:
    """The scenes `rows` of `spec` as runs.time_sample reads a plan: run m is scene rows[m]."""

    def __init__(self, spec: S.Spec, rows: list):
        self.spec, self.rows = spec, rows

    @property
    def n_models(self) -> int:
        return len(self.rows)

    def model_vals(self, m: int) -> dict:
        return self.spec.resolve(self.rows[m])


def _time_rows(sample: _Rows, simulate: Callable | None, budget: float) -> tuple:
    """On a worker: runs.time_sample of every run of `sample`."""
    return runs.time_sample(sample, simulate, budget=budget, most=sample.n_models)


def time_sample(scheduler: str | None, plan, simulate: Callable | None = None, budget: float = 2.0,
                most: int = 64) -> tuple:
    """runs.warm_up and runs.time_sample of `plan` (sweep/plan.py's Plan) on the cluster at
    `scheduler`: every worker warmed up with one run of each of the plan's variants (warm_up),
    then the runs that time_sample would time (spread evenly over the sweep) timed on one worker.
    Returns (the seconds the warm-up took, (seconds per model run, runs timed, {model run: its
    seconds})), as run_sweep records them: nothing runs in this process."""
    ids = np.unique(np.linspace(0, plan.n_models - 1, min(most, plan.n_models)).round().astype(int))
    sample = _Rows(plan.spec, [int(plan.first_row[m]) for m in ids])
    variants = [int(plan.first_row[m]) for m in plan.variants.values()]
    with connect(scheduler) as client:
        warmed = warm_up(client, plan.spec, variants, simulate)
        per_run, n, timed = client.submit(_time_rows, sample, simulate, budget, pure=False).result()
    return warmed, (per_run, n, {int(ids[k]): seconds for k, seconds in timed.items()})


@contextlib.contextmanager
def mapper(scheduler: str | None, fn: Callable, shared, warm: tuple | None = None) -> Iterator[Callable]:
    """A map over the workers of the cluster at `scheduler`, for scipy's `workers=`: map(func, xs)
    gives [fn(x, shared=shared) for x in xs], in the order of xs, computed on the workers (the
    result is the same as a local map's). `shared` goes to every worker once, not with each task;
    `func`, the objective scipy wraps, is not sent: `fn` with `shared` must compute the same (it
    is the objective with the context this process holds, as an argument). `warm` as connect's."""
    with connect(scheduler, warm) as client:
        held = _send(client, shared)

        def map_(func: Callable, xs) -> list:
            return client.gather(client.map(fn, list(xs), shared=held, pure=False))

        yield map_
