"""Where the warm cycle kernel's time goes, by compiled function, on this machine's own build: the
time beside instructions.py's counts (callgrind counts instructions of a build for the CPU valgrind
emulates, which need not track the time: results/kernel_cuts.md).

    python benchmarks/time_profile.py [--passes 40] [--step-factor 1] [--out results/time_profile.md]

Linux `perf record` samples the CPU clock (no hardware counters needed) of one process that
compiles the kernel afresh (an empty Numba cache of its own, so that the entry point's module, and
the address of each function left a function of its own, are at hand: written where perf looks for a
JIT's symbols, perf's map file of the process), then runs the main job's fixed 60-scene sample
through `run_cycles` as instructions.py does, with sampling switched on only around that loop
(perf's control fifo). A function's share holds the code inlined into it (kernel/jit.py
kernel(inline=True): the right-hand side inside cycle_step, accept inside cycle_loop) and not its
calls of the functions that are not inlined; libm's functions are rows of their own.
"""
from __future__ import annotations

import argparse
import os
import re
import subprocess
import sys
import tempfile
from pathlib import Path

from common import ROOT, md_table, sample_runs

OUT = ROOT / "results" / "time_profile.md"

#: the profiled process after the sample's set-up (common.sample_runs): the perf map, then the timed passes
WORKER = r"""
import time
n, ctl, ack = int(sys.argv[1]), sys.argv[2], sys.argv[3]
lib = next(iter(run_cycles.overloads.values())).library
engine = lib._codegen._engine
addrs = sorted((engine.get_function_address(f.name), f.name) for f in lib._final_module.functions
               if not f.is_declaration)
addrs = [a for a in addrs if a[0]]
with open(f"/tmp/perf-{os.getpid()}.map", "w") as fh:  # perf's place for a JIT's symbols
    for (a, name), (b, _) in zip(addrs, addrs[1:] + [(addrs[-1][0] + 65536, "")]):
        fh.write(f"{a:x} {b - a:x} {name}\n")
def say(word):
    with open(ctl, "w") as fh:
        fh.write(word + "\n")
    with open(ack) as fh:
        fh.readline()
say("enable")
t = time.perf_counter()
for _ in range(n):
    for a in args:
        run_cycles(*a)
seconds = time.perf_counter() - t
say("disable")
print(os.getpid(), seconds / (n * len(args)) * 1e3)
"""


def name_of(symbol: str) -> str:
    """`module.function` of a mangled kernel symbol (the last two of its leading name parts)."""
    words, rest = [], symbol[3:] if symbol.startswith("_ZN") else ""
    while (m := re.match(r"\d+", rest)):
        k = int(m.group())
        words.append(rest[m.end():m.end() + k])
        rest = rest[m.end() + k:]
    return ".".join(words[-2:]) if words else symbol


def profile(passes: int, step_factor: float = 1.0) -> tuple[float, list]:
    """ms a cycle and [(function, share of the kernel's samples)], from a fresh process."""
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        ctl, ack, data = tmp / "ctl", tmp / "ack", tmp / "perf.data"
        os.mkfifo(ctl)
        os.mkfifo(ack)
        env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp / "cache"), "PYTHONPATH": str(ROOT)}
        run = subprocess.run(["perf", "record", "-e", "cpu-clock", "-F", "10000", "-D", "-1", "--control",
                              f"fifo:{ctl},{ack}", "-o", str(data), "--", sys.executable, "-c",
                              sample_runs(step_factor) + WORKER, str(passes), str(ctl), str(ack)], env=env, capture_output=True, text=True, cwd=ROOT)
        if run.returncode:
            raise SystemExit(f"perf record failed:\n{run.stderr[-3000:]}")
        pid, ms = run.stdout.strip().splitlines()[-1].split()
        rep = subprocess.run(["perf", "report", "-i", str(data), "--stdio", "--sort", "dso,sym", "--percentage",
                              "relative"], capture_output=True, text=True)
        Path(f"/tmp/perf-{pid}.map").unlink(missing_ok=True)  # read by the report only
    ms = float(ms)
    rows = []
    for line in rep.stdout.splitlines():
        m = re.match(r"\s*([\d.]+)%\s+(.+?)\s+\[[.k]\]\s+(\S+)", line)
        if m:
            rows.append((m.group(2).strip(), name_of(m.group(3)), float(m.group(1))))
    return ms, rows


def page(ms: float, rows: list, passes: int, step_factor: float) -> str:
    flag = f" --step-factor {step_factor:g}" if step_factor != 1.0 else ""
    at = f", at step_factor {step_factor:g}" if flag else ""
    lines = ["# Where a warm cycle's time goes, by compiled function", "",
             f"Regenerate: `python benchmarks/time_profile.py --passes {passes}{flag}` (what is measured: its "
             f"docstring). The main job's 60-scene sample through `run_cycles`{at}, "
             f"{passes} passes, this machine's build: "
             f"**{ms:.4f} ms a cycle** while sampled.", ""]
    table = [[f"`{name}`" if "[JIT]" in dso else f"{name} ({dso})", f"{share:.1f} %", f"{share / 100 * ms * 1e3:.1f}"]
             for dso, name, share in rows if share >= 0.1]
    return "\n".join(lines + md_table(["function (what is inlined into it counts as its own)", "share>",
                                       "us a cycle>"], table)) + "\n"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--passes", type=int, default=40)
    ap.add_argument("--step-factor", type=float, default=1.0, help="the sample's step_factor (TOL x its 5th power)")
    ap.add_argument("--out", default=str(OUT))
    args = ap.parse_args()
    ms, rows = profile(args.passes, args.step_factor)
    text = page(ms, rows, args.passes, args.step_factor)
    print(text)
    Path(args.out).write_text(text)


if __name__ == "__main__":
    main()
