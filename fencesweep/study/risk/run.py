"""`fencesweep risk SPEC`: the probabilities that a parcel of a mix is hit too hard, not scraped,
deflects the fence too far or leaves it ringing, per element and operating point.

1. The population's first `cap` parcels are drawn once (spec/population.py): sample k is the same
   for every unit, any --jobs and any backend (common random numbers: the units' estimates are
   compared on the same parcels).
2. Round after round (risk/sequential.py run_rounds), the units still undecided run their samples
   [n_j-1, n_j) as cycles: cut into chunks of at most CHUNK_CYCLES, run in this process, on local
   workers or on Dask (sweep/compute.py run_calls, as the sweeps run theirs), each written into
   OUT.partial/<salt>/ as it finishes, named by the run's salt and its content. A killed run
   keeps its chunks; the same command again finds them (the rounds ask for the same chunks, the
   decisions depending only on the results) and runs only the rest.
3. The table (risk/table.py): one row per unit, and OUT_samples.parquet (every cycle) with
   risk.samples: true.
Orchestration only: it draws parameters and counts results; the physics is the engine's.
"""
from __future__ import annotations

import contextlib
import hashlib
import json
import shutil
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

import numpy as np

from fencesweep.model import params as P
from fencesweep.study.risk import sequential as SQ
from fencesweep.study.spec import population as PO
from fencesweep.study.spec.risk import RiskSpec
from fencesweep.study.store import table as store
from fencesweep.study.sweep import compute, runs
from fencesweep.study.sweep.progress import bar as progress_bar

VERSION = 1  # of the sampling and its chunks; in the salt
CHUNK_CYCLES = 256  # cycles per chunk, at most (a few tenths of a second)
COLUMNS = ("outcome", "overload", "deflection_max", "residual_amplitude", "dalpha_perm", "peak_force", "n_steps",
           "status")
PLAN_FILE = "risk.json"


@dataclass
class Bundle:
    """What every chunk of a risk run shares: the spec and the drawn parcels."""

    spec: RiskSpec
    parcels: dict  # {L, A, m1, dP, R_s, phi0: arrays of cap}


def salt(sp: RiskSpec) -> str:
    """Digest of the spec, the engine's sources and VERSION: names the work directory."""
    return hashlib.sha256(f"{sp.hash}:{store.source_hash()}:risk:{VERSION}".encode()).hexdigest()


def work_dir(sp: RiskSpec, out: Path) -> Path:
    return Path(str(out) + ".partial") / salt(sp)[:16]


def saved_chunks(sp: RiskSpec, out: Path) -> tuple:
    """(work directory, chunks saved in it, None) of an interrupted risk run."""
    work = work_dir(sp, out)
    return work, len(list(work.glob("chunk-*.parquet"))) if work.exists() else 0, None


def unit_values(sp: RiskSpec, parcels: dict, unit: int, i: int) -> dict:
    """The resolved parameters of sample i of `unit` (params.resolve: the engine's checks)."""
    load = {c: float(parcels[c][i]) for c in PO.SIZES + PO.PLACES}
    return P.resolve("cycle", **sp.inputs(unit), **load)


def run_pieces(k: int, pieces: list, path: str | None, shared: tuple | None = None) -> tuple:
    """Run one chunk: pieces (unit, start, stop) of samples; write it at `path` (local workers) or
    return its columns (Dask): (k, columns or None, cycles)."""
    bundle, simulate = compute.shared(shared)
    cols = {c: [] for c in ("unit", "sample", *COLUMNS)}
    for unit, start, stop in pieces:
        for i in range(start, stop):
            try:
                vals = unit_values(bundle.spec, bundle.parcels, unit, i)
                res = runs.run_one("cycle", vals, simulate)
                dlim = vals["dalpha_perm"]
            except P.ParameterError as exc:  # a start the spec's checks let through: recorded, never silent
                res, dlim = store.failed_result("cycle", f"failed: {exc}"), np.nan
            cols["unit"].append(unit)
            cols["sample"].append(i)
            for c in COLUMNS:
                cols[c].append(dlim if c == "dalpha_perm" else res.get(c))
    if path is None:
        return k, cols, sum(b - a for _, a, b in pieces)
    _write(path, cols)
    return k, None, sum(b - a for _, a, b in pieces)


def _write(path, cols: dict) -> None:
    import pyarrow as pa

    types = {"unit": pa.int64(), "sample": pa.int64(), "outcome": pa.string(), "status": pa.string(),
             "n_steps": pa.int64()}
    table = pa.table({c: pa.array(v, type=types.get(c, pa.float64())) for c, v in cols.items()})
    store.write_table_atomic(table, path, fsync=False, attrs={})


def chunks_of(units: np.ndarray, start: int, stop: int, key: str, look: int) -> list:
    """(file name, pieces) of a round: the units' samples [start, stop) in chunks of at most
    CHUNK_CYCLES cycles, each named by a digest of the salt, the look and its pieces."""
    pieces, out, size = [], [], 0
    for u in units.tolist():
        a = start
        while a < stop:
            b = min(stop, a + CHUNK_CYCLES - size)
            pieces.append((u, a, b))
            size += b - a
            a = b
            if size == CHUNK_CYCLES:
                out.append(pieces)
                pieces, size = [], 0
    if pieces:
        out.append(pieces)
    named = []
    for k, part in enumerate(out):
        h = hashlib.sha256(f"{key}:{look}:{k}:{part}".encode()).hexdigest()[:16]
        named.append((f"chunk-R{look:02d}-{k:05d}-{h}.parquet", part))
    return named


def _complete(path: Path) -> bool:
    import pyarrow as pa
    import pyarrow.parquet as pq

    try:
        pq.read_metadata(path)
    except (OSError, pa.ArrowInvalid):
        return False
    return True


class Rounds:
    """The engine behind run_rounds' evaluate: each round's chunks run (or found) and read back."""

    def __init__(self, bundle: Bundle, work: Path, key: str, run: dict, bar):
        self.bundle, self.work, self.key, self.run, self.bar = bundle, work, key, run, bar
        self.look = 0
        self.names: list = []
        self.computed = self.reused = 0

    def __call__(self, units: np.ndarray, start: int, stop: int) -> np.ndarray:
        chunks = chunks_of(units, start, stop, self.key, self.look)
        self.look += 1
        self.names += [name for name, _ in chunks]
        pending = [k for k, (name, _) in enumerate(chunks) if not _complete(self.work / name)]
        self.reused += len(chunks) - len(pending)
        self.computed += len(pending)
        self.bar.total = (self.bar.total or 0) + len(units) * (stop - start)
        todo = set(pending)
        self.bar.update(sum(b - a for k, (_, part) in enumerate(chunks) if k not in todo for _, a, b in part))
        if pending:
            self._run(chunks, pending)
        return self._events(chunks, units, start, stop)

    def _run(self, chunks: list, pending: list) -> None:
        r = self.run
        cycles = sum(b - a for k in pending for _, a, b in chunks[k][1])
        jobs = runs.local_jobs(r["jobs"], cycles * r["per_cycle"]) if r["local"] else r["jobs"]
        shared = (self.bundle, r["simulate"])

        def calls(where: str):
            for k in pending:
                name, part = chunks[k]
                yield (run_pieces, k, part, str(self.work / name) if where != "dask" else None,
                       shared if where != "pool" else None)

        t = time.perf_counter()
        with contextlib.ExitStack() as stack:
            for k, cols, n in compute.run_calls(stack, calls, jobs, r["local"], r["scheduler"], shared):
                if cols is not None:  # Dask: this process writes
                    _write(self.work / chunks[k][0], cols)
                self.bar.update(n)
        r["per_cycle"] = (time.perf_counter() - t) * (jobs if r["local"] else 1) / max(cycles, 1)

    def _events(self, chunks: list, units: np.ndarray, start: int, stop: int) -> np.ndarray:
        """bool [units, stop - start, EVENTS] from the round's chunks (counting, not physics)."""
        df = read_chunks([self.work / name for name, _ in chunks])
        ev = events(df, self.bundle.spec.limits)
        at = {u: j for j, u in enumerate(units.tolist())}
        out = np.zeros((len(units), stop - start, len(SQ.EVENTS)), dtype=bool)
        rows = np.array([at[u] for u in df["unit"].to_numpy()], dtype=np.int64)
        out[rows, df["sample"].to_numpy() - start] = ev
        return out


def read_chunks(paths: list):
    import pandas as pd

    return pd.concat([pd.read_parquet(p) for p in paths], ignore_index=True)


def events(df, limits) -> np.ndarray:
    """Per cycle, whether it broke each constraint (EVENTS order): overload > limit (no contact:
    none), outcome not scraped (a failed run counts here), deflection_max > its limit,
    residual_amplitude > its limit."""
    dlim = df["dalpha_perm"].to_numpy(float) if limits.deflection_max is None else limits.deflection_max
    return np.stack([df["overload"].fillna(0.0).to_numpy(float) > limits.overload,
                     df["outcome"].to_numpy() != "scraped",
                     df["deflection_max"].fillna(0.0).to_numpy(float) > dlim,
                     df["residual_amplitude"].fillna(0.0).to_numpy(float) > limits.residual_amplitude], axis=1)


def _open_work(sp: RiskSpec, out: Path, resume: bool, log: Callable) -> Path:
    from fencesweep.study.sweep import output

    work = work_dir(sp, out)
    output.open_work(work.parent, work, resume, log)
    with store.atomic_path(work / PLAN_FILE, fsync=False) as tmp:
        tmp.write_text(json.dumps({"spec_hash": sp.hash, "spec_path": sp.path, "salt": salt(sp)}, indent=1))
    return work


def run_risk(sp: RiskSpec, out: Path, jobs: int, resume: bool = True, local: bool = True, scheduler: str | None = None,
             progress: bool = False, log: Callable = print, simulate: Callable | None = None) -> dict:
    """The risk study of `sp` into `out` (module docstring); the caller holds the output's lock.
    Returns the run's record (risk/table.py write: what the table's attrs hold under "run")."""
    from fencesweep.study.risk import table as RT

    t0 = time.perf_counter()
    parcels = PO.draw(sp.population, sp.cap)
    bundle = Bundle(sp, parcels)
    work = _open_work(sp, out, resume, log)
    warm = time.perf_counter()
    (simulate or runs.engine())(unit_values(sp, parcels, 0, 0), trajectory=False)  # loads the kernels before forking
    warm = time.perf_counter() - warm
    run = {"jobs": jobs, "local": local, "scheduler": scheduler, "simulate": simulate, "per_cycle": 2e-3}
    name = Path(sp.path).stem if sp.path else "risk"
    bar = progress_bar(0, f"{name} (risk)", progress, unit="cycle")
    rounds = Rounds(bundle, work, salt(sp), run, bar)
    try:
        state = SQ.run_rounds(len(sp.units), rounds, sp.plan(), sp.p_max)
    finally:
        bar.close()
    record = {"seconds": None, "jobs": jobs if local else None, "warm_up": warm, "cycles": state.cycles,
              "chunks_computed": rounds.computed, "chunks_reused": rounds.reused, "rounds": state.rounds}
    samples = read_chunks([work / n for n in rounds.names]) if rounds.names else None
    record["seconds"] = time.perf_counter() - t0
    record |= RT.write(sp, out, state, parcels, samples, record)
    shutil.rmtree(work.parent)
    return record
