"""What does a GPU give against the CPU? On the same machine: cycles per second, kernel and end-to-end
time, and the tables compared row by row (results/gpu.md).

    python benchmarks/gpu.py [--specs sweeps/envelope.yaml sweeps/b2k2.yaml] [--sample 2048]
                             [--out results/gpu.md] [--json FILE]       on a machine with a GPU
    python benchmarks/gpu.py --stand-in [--specs ...]                   the GPU path's CPU side here
    NUMBA_ENABLE_CUDASIM=1 python benchmarks/gpu.py --smoke --out F     the script itself, on Numba's
                                                                        CUDA simulator (two cycles)

Per spec, each run a fresh process through `run_grid` (the CLI's call): gpu cold (--backend cuda, an
empty Numba cache: the numba-cuda compile included), gpu warm (its "gpu" seconds: the batches' launch
to results back), cpu all (--backend loky on all cores, warm), cpu 1 core (`--sample` runs spread
evenly over the spec, one after another in one warm process). The GPU's cycles per second are the runs
over the warm run's "gpu" seconds; the bar is 100x one core. The tables (gpu warm, cpu all) are
compared row by row: equal outcomes, every value within |a - b| <= 1e-6 max(1, |a|), n_steps within a
few; a row over it is re-run on the CPU at tol / 10, and where the CPU's own value is as far from that
the CPU's verification would flag the row too (counted apart).

--stand-in, without a GPU: the card replaced by a stand-in that answers each batch at once with a real
cycle's result row (unverified: the rows are not the scenes'), so what remains is the GPU path's CPU
side: planning, the parameter vectors, the chunks and the table.

On the device machine (no network; numba-cuda in its image), from the repository root:
    PYTHONUNBUFFERED=1 PYTHONPATH=. python3 benchmarks/gpu.py --out $OUT/gpu.md --json $OUT/gpu.json
"""
from __future__ import annotations

import argparse
import json
import os
import tempfile
import time
from pathlib import Path

import numpy as np
from common import ROOT, md_table, run_json

OUT = ROOT / "results" / "gpu.md"
SMOKE_SPEC = """\
description: the benchmark's smoke test on the simulator
scene: cycle
cases: [small_far, long_near]
params: {B2: 40.0}
output: smoke.parquet
"""

#: one sweep in a fresh process: run_grid's record and the command's wall seconds
SWEEP = r"""
import json, sys, time
t0 = time.perf_counter()
from fencesweep.study import api
spec, out, backend, jobs, verify = sys.argv[1], sys.argv[2], sys.argv[3], int(sys.argv[4]), sys.argv[5] == "1"
if len(sys.argv) > 6:  # --stand-in: the card replaced (benchmarks/gpu.py stand_in)
    sys.path.insert(0, sys.argv[6]); import gpu as bench; bench.stand_in()
run = api.run_grid(spec, out=out, jobs=jobs, backend=backend, overwrite=True, resume=False, progress=False,
                   verify=None if verify else False)
print(json.dumps({"wall": time.perf_counter() - t0, "seconds": run["seconds"], "timings": run["timings"],
                  "runs": run["model_runs"], "verify": run["verify"]}))
"""

#: one core's cycles per second on `n` runs spread evenly over the spec, warm
ONE_CORE = r"""
import json, sys, time
import numpy as np
from fencesweep.model.simulate import simulate_resolved
from fencesweep.study.spec import file as F
from fencesweep.study.spec.scenes import Scenes
spec = F.load(sys.argv[1]); n = int(sys.argv[2])
rows = np.unique(np.linspace(0, spec.n_scenes - 1, n).round().astype(np.int64))
vals = Scenes(spec).resolved(rows)
simulate_resolved(vals[0])  # the kernels loaded
t = time.perf_counter()
for v in vals:
    simulate_resolved(v)
print(json.dumps({"runs": len(vals), "seconds": time.perf_counter() - t}))
"""


def _python(code: str, *args, env: dict | None = None) -> dict:
    return run_json(code, *args, env={"PYTHONPATH": str(ROOT), **(env or {})})


def stand_in() -> None:
    """In a sweep's process: backend cuda with the card replaced (module docstring)."""
    from fencesweep.model import params as P
    from fencesweep.model.simulate import simulate_resolved
    from fencesweep.model.results import RI
    from fencesweep.study.sweep import gpu, pipeline

    res, _ = simulate_resolved(P.resolve("cycle", "small_far"))
    row = np.zeros(40)
    for name, i in RI.items():
        v = res[name]
        row[i] = {"scraped": 0}.get(v, 0) if isinstance(v, str) else float(v)

    class Done:
        def __init__(self, n):
            self.result = lambda: np.tile(row, (n, 1))

    class StandIn:
        free_memory = staticmethod(lambda: None)
        launch = staticmethod(lambda P: Done(P.shape[0]))

    pipeline.gpu_device = lambda spec: {"backend": "cuda", "name": "stand-in (no GPU)"}
    gpu.runner = lambda: StandIn()


def _close(a, b) -> np.ndarray:
    """|a - b| <= 1e-6 max(1, |a|), NaN where both are."""
    a, b = np.asarray(a, float), np.asarray(b, float)
    return (np.isnan(a) & np.isnan(b)) | (np.abs(a - b) <= 1e-6 * np.maximum(1.0, np.abs(a)))


def compare(cpu_path: Path, gpu_path: Path, spec_path: str) -> dict:
    """The two tables row by row (module docstring); rows over 1e-6 re-run on the CPU at tol / 10."""
    import pandas as pd

    from fencesweep.study.store import table as store

    a, b = pd.read_parquet(cpu_path), pd.read_parquet(gpu_path)
    same_outcome = (a["outcome"] == b["outcome"]).to_numpy()
    results = [f.name for f in store.table_result_fields("cycle") if a[f.name].dtype.kind == "f"]
    ok = np.ones(len(a), bool)
    worst = {}
    for c in results:
        ok &= _close(a[c], b[c])
        x, y = a[c].to_numpy(), b[c].to_numpy()
        d = np.abs(x - y) / np.maximum(1.0, np.abs(x))
        worst[c] = float(np.nanmax(d)) if np.isfinite(d).any() else 0.0
    steps = np.abs(a["n_steps"].to_numpy() - b["n_steps"].to_numpy())
    over = np.flatnonzero(~ok | ~same_outcome)
    return {"rows": len(a), "outcomes_differ": int((~same_outcome).sum()), "rows_over_1e-6": int(len(over)),
            "of_them_cpu_as_far_from_tol10": _cpu_flags(spec_path, a, over, results) if len(over) else 0,
            "n_steps_equal": float((steps == 0).mean()), "n_steps_max_diff": int(steps.max()) if len(steps) else 0,
            "worst": dict(sorted(worst.items(), key=lambda kv: -kv[1])[:6])}


def _cpu_flags(spec_path: str, a, rows, results: list) -> int:
    """Of the table rows `rows`, how many have a CPU value > 1e-6 off the CPU's re-run at tol / 10
    (row k of a table is its k-th valid scene)."""
    from fencesweep.model.simulate import simulate_resolved
    from fencesweep.study.spec import file as F
    from fencesweep.study.spec.scenes import Scenes
    from fencesweep.study.sweep.verify import STEP_FACTOR_SCALE

    spec = F.load(spec_path)
    scenes = Scenes(spec)
    valid = np.flatnonzero(scenes.keys(np.arange(spec.n_scenes))[0])
    n = 0
    for k, vals in zip(rows, scenes.resolved(valid[rows])):
        tight, _ = simulate_resolved(dict(vals, step_factor=float(vals["step_factor"]) * STEP_FACTOR_SCALE))
        n += any(not _close(a[c].iloc[k], tight[c]) for c in results if c in tight)
    return n


def _spec_file(args, tmp: Path) -> list:
    if not args.smoke:
        return args.specs
    path = tmp / "smoke.yaml"
    path.write_text(SMOKE_SPEC)
    return [str(path)]


def _runs(spec: str, tmp: Path, args) -> dict:
    name = Path(spec).stem
    jobs = os.cpu_count() or 1
    row = {"spec": spec}
    if args.stand_in:
        row["stand_in"] = _python(SWEEP, spec, tmp / f"{name}_s.parquet", "cuda", jobs, 0, ROOT / "benchmarks")
        row["cpu_all"] = _python(SWEEP, spec, tmp / f"{name}_c.parquet", "loky", jobs, 0)
        return row
    cold = {"NUMBA_CACHE_DIR": str(tmp / f"cache_{name}")}
    row["gpu_cold"] = _python(SWEEP, spec, tmp / f"{name}_g.parquet", "cuda", jobs, 1, env=cold)
    row["gpu_warm"] = _python(SWEEP, spec, tmp / f"{name}_g.parquet", "cuda", jobs, 1, env=cold)
    row["cpu_all"] = _python(SWEEP, spec, tmp / f"{name}_c.parquet", "loky", jobs, 1, env=cold)
    row["cpu_one"] = _python(ONE_CORE, spec, args.sample, env=cold)
    row["compare"] = compare(tmp / f"{name}_c.parquet", tmp / f"{name}_g.parquet", spec)
    return row


def _md(rows: list, args) -> str:
    from fencesweep.kernel import cuda

    gpus = cuda.gpus()
    head = [f"# The GPU path against the CPU (`benchmarks/gpu.py`{' --stand-in' if args.stand_in else ''})", "",
            f"Machine: {os.cpu_count()} cores; GPU: {gpus[0]['name'] if gpus else 'none'}; numba-cuda "
            f"{cuda.version()}. {time.strftime('%Y-%m-%d')}.", ""]
    if args.stand_in:
        return "\n".join(head + [
            "No GPU here: the card is replaced by a stand-in that answers each batch at once (module docstring), "
            "so these are the GPU path's CPU side alone: planning, the kernels' load and timed sample, the parameter "
            "vectors, the chunks and the table, against the whole CPU run on all cores of this machine (neither "
            "verified). `compute` is the phase in which the card would run. The GPU's own seconds await a machine "
            "with one.", "",
            *md_table(["spec", "runs>", "stand-in: command s>", "its compute s>", "cpu all cores: command s>"], [
                [r["spec"], f"{r['stand_in']['runs']:,}", f"{r['stand_in']['wall']:.2f}",
                 f"{r['stand_in']['timings'].get('compute', 0):.2f}", f"{r['cpu_all']['wall']:.2f}"] for r in rows])]) + "\n"
    table = []
    for r in rows:
        one, warm = r["cpu_one"]["runs"] / r["cpu_one"]["seconds"], r["gpu_warm"]
        rate = warm["runs"] / max(warm["timings"].get("gpu", float("nan")), 1e-9)
        table.append([r["spec"], f"{warm['runs']:,}", f"{one:,.0f}", f"{r['cpu_all']['wall']:.1f}",
                      f"{r['gpu_cold']['wall']:.1f}", f"{warm['wall']:.1f}", f"{warm['timings'].get('gpu', 0):.2f}",
                      f"{rate:,.0f}", f"{rate / one:,.0f}"])
    head += md_table(["spec", "runs>", "one core: cycles/s>", "all cores: command s>", "GPU cold: command s>",
                      "GPU warm: command s>", "GPU batches s>", "GPU cycles/s>", "x one core>"], table)
    head += ["", "Tables, GPU warm against CPU all cores, row by row:", ""]
    return "\n".join(head + [f"- {r['spec']}: {json.dumps(r['compare'])}" for r in rows]) + "\n"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--specs", nargs="+", default=["sweeps/envelope.yaml", "sweeps/b2k2.yaml"])
    ap.add_argument("--sample", type=int, default=2048, help="runs timed on one core")
    ap.add_argument("--out", type=Path, default=OUT)
    ap.add_argument("--json", type=Path, default=None)
    ap.add_argument("--stand-in", action="store_true", help="no GPU: the GPU path's CPU side (module docstring)")
    ap.add_argument("--smoke", action="store_true", help="two cycles (for the simulator)")
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        rows = []
        for spec in _spec_file(args, Path(tmp)):
            rows.append(_runs(spec, Path(tmp), args))
            print(json.dumps(rows[-1]), flush=True)
    text = _md(rows, args)
    print(text)
    args.out.write_text(text)
    if args.json is not None:
        args.json.write_text(json.dumps(rows, indent=1))


if __name__ == "__main__":
    main()
