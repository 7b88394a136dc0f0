"""Where does a warm cycle's time go, by part of the kernel? The instructions (and, with --perf, the
time) of the warm cycle kernel, `run_cycles` on the main job's fixed 60-scene sample as instructions.py
runs it, split by the part of the model or the integrator that executes them (contact slots, contact
law, friction, drive, events, peaks, dense output, stages, step control, books): a profile of the
compiled code as it is, and what to cut first.

    python benchmarks/profile_parts.py [--perf 10] [--passes 1] [--no-check] [--keep DIR] [--out FILE]
    python benchmarks/profile_parts.py --from DIR       # the page again from a folder --keep kept

writes results/profile_parts.md (~3 min on 2 cores with --perf 10: four compiles of ~30-60 s).

Method. Most kernel functions are inlined (Numba's forceinline) and JIT code has no symbols, so the
machine code is kept as it is and each instruction is asked where it came from:
  1. compile: a process with an empty, private Numba cache (FENCESWEEP_COMPILE_HELPER=0) compiles
     run_cycles with DWARF line tables and inline chains: Numba's debug info in its directives-only
     mode (no noinline, no allocas kept, no bounds checks, lifetimes not extended: nothing that changes
     the code), its compile unit emitted in full (a patch of CPUTargetOptions.finalize and DIBuilder in
     this script's processes only). It keeps the object code MCJIT loads, compiled for the CPU valgrind
     emulates (NUMBA_CPU_NAME / NUMBA_CPU_FEATURES as LLVM sees them under valgrind: no AVX-512), so
     that the counting process loads it from the cache instead of compiling again;
  2. check (unless --no-check): the same compile without line tables must give a byte-for-byte equal
     code section (.ltext): the code profiled is the production code for that CPU;
  3. count: under callgrind (--dump-instr=yes), collection on only around the loop (callgrind_control),
     a process runs `passes` passes of the 60 scenes and reports where MCJIT put each function;
  4. attribute: each instruction gets its inline chain from the object's DWARF (llvm-symbolizer
     --inlining; else addr2line -i); a call to a library (libm's sincos, pow; libc; Numba's runtime) is
     charged with its inclusive count to the call's chain; a call to a compiled function that is not
     inlined is followed as callgrind recorded it, the callee's instructions spread over its callers'
     chains in proportion to each call site's inclusive count (gprof's assumption: a callee costs the
     same whoever calls it). The calls into the code from Python must add up to what was attributed;
  5. time (--perf SECONDS): `perf record -e cpu-clock` samples the same loop, natively, for the build
     counted and for the native build (compiled and checked the same way for this machine's CPU: the
     production code, AVX-512 here); a sample is attributed as an instruction is.

Columns: "own", each instruction to the innermost package function it was inlined from (Numba's helpers
and library calls to the package line that called them; libraries have rows of their own): the rows add
up to 100 %. "inclusive": every instruction under a function of the part, however deep (parts overlap).
Per step: per accepted step, the rejected steps' work included.

Limits. Callgrind's counts are exact and repeatable, but instructions are not time (a square root costs
far more than an addition; each byte of a `rep movsb` counts as an instruction). LLVM's line of an
instruction merged from two lines or hoisted is one of them: a share of a few tenths of a percent says
little. perf's samples land on the instruction the core waits for; ~10^5 samples give a share to a
few tenths of a percent.
"""
from __future__ import annotations

import argparse
import collections
import json
import os
import re
import shutil
import struct
import subprocess
import sys
import tempfile
from pathlib import Path

from common import md_row, md_table

ROOT = Path(__file__).resolve().parents[1]
OUT = ROOT / "results" / "profile_parts.md"
N_SCENES = 60


# ------------------------------------------------------------------ inside the worker processes
def line_tables() -> None:
    """Numba compiles with DWARF line tables and inline chains, and nothing else changed in the
    code (module docstring, step 1): debug info directives-only for the lowering, full for the
    compile unit; no bounds checks, no extended lifetimes."""
    from numba.core import cpu, debuginfo

    finalize, init = cpu.CPUTargetOptions.finalize, debuginfo.DIBuilder.__init__

    def finalize_with_lines(self, flags, options):
        flags.debuginfo = True
        flags.dbg_directives_only = True
        flags.dbg_extend_lifetimes = False
        flags.boundscheck = False
        finalize(self, flags, options)

    def init_full(self, module, filepath, cgctx, directives_only):
        init(self, module, filepath, cgctx, False)

    cpu.CPUTargetOptions.finalize = finalize_with_lines
    debuginfo.DIBuilder.__init__ = init_full


def sample_args():
    """run_cycles' arguments for the main job's fixed sample (benchmarks/asv_bench main_job_sample),
    one cycle each, as instructions.py makes them."""
    import numpy as np

    sys.path.insert(0, str(ROOT / "benchmarks"))
    from asv_bench import main_job_sample
    from fencesweep.model import layout as Lp
    from fencesweep.model import params as P
    from fencesweep.model.prepare import prepare
    from fencesweep.model import results as Rs
    from fencesweep.model.scenes.cycle.layout import N_TRAJ

    args = []
    for case, b2, k2 in main_job_sample(N_SCENES):
        p = prepare(P.resolve("cycle", case, B2=b2, K2=k2))
        loads = np.ascontiguousarray(p[list(Lp.LOAD_SLOTS)][None, :])
        args.append((p, loads, float(p[Lp.TC]), np.empty((1, Rs.N_STREAM_CYCLE_RESULTS)), np.empty((0, N_TRAJ)),
                     np.zeros(2, np.int64)))
    return args


def worker(mode: str, obj: Path, passes: int) -> None:
    """A worker process. mode "compile" / "compile-plain": compile run_cycles (with / without line
    tables) and write its object code to obj. mode "count": print the address of every function
    of the object obj and the steps the sample takes, then run the sample `passes` times with
    callgrind's collection on around the loop; mode "loop": the same, then run the sample until
    stdin is closed (perf samples it meanwhile)."""
    if mode != "compile-plain":
        line_tables()
    from fencesweep.model import results as Rs
    from fencesweep.model.scenes.stream import run_cycles

    args = sample_args()
    run_cycles(*args[0])
    library = run_cycles.overloads[run_cycles.signatures[0]].library
    if mode.startswith("compile"):
        obj.write_bytes(library._get_compiled_object())
        return
    engine = library._codegen._engine
    for name, (offset, size) in elf_functions(obj.read_bytes()).items():
        print(f"FUNC {engine.get_function_address(name):#x} {offset:#x} {size} {name}", flush=True)
    steps = rejects = 0
    for a in args:
        run_cycles(*a)
        steps += a[3][0, Rs.RC_N_STEPS]
        rejects += a[3][0, Rs.RC_N_REJECTED]
    print(f"STEPS {steps:.0f} {rejects:.0f}", flush=True)
    if mode == "count":
        pid = str(os.getpid())
        subprocess.run(["callgrind_control", "-i", "on", pid], capture_output=True)
        for _ in range(passes):
            for a in args:
                run_cycles(*a)
        subprocess.run(["callgrind_control", "-i", "off", pid], capture_output=True)
        return
    import select

    print("READY", flush=True)
    while not select.select([sys.stdin], [], [], 0)[0]:
        for a in args:
            run_cycles(*a)


# ------------------------------------------------------------------ the ELF object
def elf_sections(data: bytes) -> list[tuple[str, int, int, int]]:
    """(name, type, file offset, size) of each section of an ELF64 little-endian object."""
    shoff, = struct.unpack_from("<Q", data, 0x28)
    shentsize, shnum, shstrndx = struct.unpack_from("<HHH", data, 0x3A)
    raw = [struct.unpack_from("<IIQQQQIIQQ", data, shoff + i * shentsize) for i in range(shnum)]
    strtab_off = raw[shstrndx][4]

    def name(i):
        end = data.index(b"\0", strtab_off + i)
        return data[strtab_off + i:end].decode()

    return [(name(s[0]), s[1], s[4], s[5]) for s in raw]


def elf_functions(data: bytes) -> dict[str, tuple[int, int]]:
    """{symbol: (offset in its section, size)} of the object's defined functions."""
    secs = elf_sections(data)
    shoff, = struct.unpack_from("<Q", data, 0x28)
    shentsize, = struct.unpack_from("<H", data, 0x3A)
    out = {}
    for k, (_, typ, off, size) in enumerate(secs):
        if typ != 2:  # SHT_SYMTAB
            continue
        link = struct.unpack_from("<I", data, shoff + k * shentsize + 40)[0]
        str_off = secs[link][2]
        for e in range(0, size, 24):
            st_name, st_info, _, st_shndx, value, sz = struct.unpack_from("<IBBHQQ", data, off + e)
            if st_info & 0xF == 2 and st_shndx != 0:  # STT_FUNC, defined
                nm = data[str_off + st_name:data.index(b"\0", str_off + st_name)].decode()
                out[nm] = (value, sz)
    return out


def code_section(data: bytes) -> bytes:
    """The bytes of the object's code (.ltext: Numba's large code model; .text when empty)."""
    secs = {name: (off, size) for name, _, off, size in elf_sections(data)}
    off, size = secs[".ltext"] if secs.get(".ltext", (0, 0))[1] else secs[".text"]
    return data[off:off + size]


# ------------------------------------------------------------------ running the workers
def valgrind_cpu() -> tuple[str, str]:
    """The CPU name and features LLVM sees under valgrind (which emulates no AVX-512): the
    callgrind build is compiled for them, natively as under valgrind, so that the counted
    process loads the cached code instead of compiling another."""
    code = "import llvmlite.binding as ll; print(ll.get_host_cpu_name()); print(ll.get_host_cpu_features().flatten())"
    out = subprocess.run(["valgrind", "-q", sys.executable, "-c", code], capture_output=True, text=True, check=True)
    name, features = out.stdout.split()[:2]
    return name, features


def _env(cache: Path, cpu: tuple[str, str] | None) -> dict:
    env = dict(os.environ, NUMBA_CACHE_DIR=str(cache), FENCESWEEP_COMPILE_HELPER="0", PYTHONHASHSEED="0")
    for key in ("NUMBA_DISABLE_JIT", "NUMBA_DEBUGINFO", "NUMBA_BOUNDSCHECK", "NUMBA_OPT", "NUMBA_CPU_NAME",
                "NUMBA_CPU_FEATURES"):
        env.pop(key, None)
    if cpu is not None:
        env["NUMBA_CPU_NAME"], env["NUMBA_CPU_FEATURES"] = cpu
    return env


def _worker_cmd(mode: str, obj: Path, passes: int = 1) -> list[str]:
    return [sys.executable, str(Path(__file__).resolve()), "--worker", mode, "--obj", str(obj),
            "--passes", str(passes)]


def compile_object(mode: str, cache: Path, obj: Path, cpu) -> bytes:
    """Compile run_cycles in a new process into the empty cache `cache`; its object code."""
    subprocess.run(_worker_cmd(mode, obj), env=_env(cache, cpu), cwd=ROOT, check=True, capture_output=True)
    return obj.read_bytes()


def parse_worker(text: str):
    """The worker's report: {symbol: (runtime address, offset, size)}, (steps, rejected steps)."""
    funcs, steps = {}, None
    for line in text.splitlines():
        f = line.split()
        if f and f[0] == "FUNC":
            funcs[f[4]] = (int(f[1], 16), int(f[2], 16), int(f[3]))
        elif f and f[0] == "STEPS":
            steps = (float(f[1]), float(f[2]))
    return funcs, steps


def short_name(symbol: str) -> str:
    """The function's own name in a Numba symbol (_ZN<len><name>...<len><name>B...E...)."""
    out, i = symbol, 3 if symbol.startswith("_ZN") else len(symbol)
    while i < len(symbol) and symbol[i].isdigit():
        digits = re.match(r"\d+", symbol[i:]).group()
        i += len(digits)
        out = symbol[i:i + int(digits)]
        i += int(digits)
    return out


def text_base(funcs: dict) -> int:
    """Where MCJIT put the object's code: each function's address minus its offset, the same for
    all but the weak ones another library defined first (NRT_incref); every function of the
    package must agree (else the process ran other code than the object's)."""
    bases = collections.Counter(addr - off for addr, off, _ in funcs.values())
    base = bases.most_common(1)[0][0]
    wrong = [n for n, (addr, off, _) in funcs.items() if addr - off != base and "fencesweep" in n]
    if wrong or not base:
        raise SystemExit(f"the object's functions are not where its symbol table puts them: {wrong[:3]}")
    return base


def run_callgrind(cache: Path, obj: Path, passes: int, out: Path, cpu):
    """Count the sample's instructions under callgrind (module docstring, step 3): (instructions
    collected, the worker's report)."""
    cmd = ["valgrind", "--tool=callgrind", "--instr-atstart=no", "--dump-instr=yes", "--dump-line=no",
           "--compress-strings=no", "--compress-pos=no", f"--callgrind-out-file={out}",
           *_worker_cmd("count", obj, passes)]
    proc = subprocess.run(cmd, env=_env(cache, cpu), cwd=ROOT, capture_output=True, text=True)
    m = re.search(r"Collected : (\d+)", proc.stderr)
    if proc.returncode or not m:
        raise SystemExit(f"callgrind failed:\n{proc.stderr[-3000:]}")
    return int(m.group(1)), parse_worker(proc.stdout)


def parse_callgrind(path: Path):
    """From an uncompressed callgrind file (positions: instr): the self cost of each address of
    code without an object file (JIT code: "???"; a library's addresses are relative to it, so
    only these are absolute), and the calls as (site, target, calls, inclusive cost, target's
    name), site or target None where it lies in a library."""
    self_cost = collections.Counter()
    calls = []
    jit = cob = cfn = None
    pending = None  # the calls= line, costed by the next line
    with open(path) as fh:
        for line in fh:
            c = line[0]
            if c == "0":
                addr, _, cost = line.partition(" ")
                addr, cost = int(addr, 16), int(cost or 0)
                if pending is not None:
                    target, n, name = pending
                    calls.append((addr if jit else None, target, n, cost, name))
                    pending = None
                elif jit:
                    self_cost[addr] += cost
            elif line.startswith("calls="):
                n, target = line[6:].split()[:2]
                callee_jit = (cob if cob is not None else jit)
                pending = (int(target, 16) if callee_jit else None, int(n), cfn)
                cob = None
            elif line.startswith("ob="):
                jit = line[3:].strip() == "???"
            elif line.startswith("cob="):
                cob = line[4:].strip() == "???"
            elif line.startswith("cfn="):
                cfn = line[4:].strip()
            elif line.startswith("positions:") and line.split()[1:] != ["instr"]:
                raise SystemExit(f"unexpected callgrind positions: {line}")
    return self_cost, calls


# ------------------------------------------------------------------ from addresses to source
Frame = tuple  # (function, file relative to the repository or Numba's, line), innermost first


def _short_file(path: str) -> str:
    p = Path(path)
    try:
        return p.resolve().relative_to(ROOT).as_posix()
    except ValueError:
        parts = p.parts
        return "/".join(parts[parts.index("numba"):]) if "numba" in parts else p.name


def symbolize(obj: Path, offsets: list[int]) -> dict[int, list[Frame]]:
    """The inline chain (innermost frame first) of each code offset of the object, from its DWARF."""
    text = "".join(f"{o:#x}\n" for o in offsets)
    if shutil.which("llvm-symbolizer"):
        out = subprocess.run(["llvm-symbolizer", f"--obj={obj}", "--inlining", "--functions=short"], input=text,
                             capture_output=True, text=True, check=True).stdout
        blocks = out.split("\n\n")
    else:  # binutils: "0xaddr" line, then function / file:line pairs
        out = subprocess.run(["addr2line", "-e", str(obj), "-a", "-i", "-f", "-C"], input=text, capture_output=True,
                             text=True, check=True).stdout
        blocks = re.split(r"^0x[0-9a-f]+\n", out, flags=re.M)[1:]
    chains = {}
    for o, block in zip(offsets, blocks):
        lines = [ln for ln in block.strip("\n").split("\n") if ln]
        chain = []
        for fn, loc in zip(lines[::2], lines[1::2]):
            path, _, rest = loc.partition(":")
            line = rest.split(":")[0]
            chain.append((fn, _short_file(path), int(line) if line.isdigit() else 0))
        chains[o] = chain
    if len(chains) != len(offsets):
        raise SystemExit("the symbolizer answered for fewer addresses than it was asked")
    return chains


def normal_files(chains: dict) -> dict:
    """The chains with each package frame's file made the one that defines its function: LLVM
    gives a few instructions merged from two lines the file of one and the function of the other
    (tens of addresses in thousands). Where several files define the name, the one that most
    frames of that name have."""
    defs = collections.defaultdict(set)
    for path in (ROOT / "fencesweep").rglob("*.py"):
        for m in re.finditer(r"^def (\w+)", path.read_text(), re.M):
            defs[m.group(1)].add(path.relative_to(ROOT).as_posix())
    votes = collections.Counter(f[:2] for chain in chains.values() for f in chain if f[1] in defs.get(f[0], ()))

    def fix(frame):
        fn, file, line = frame
        if not file.startswith("fencesweep/") or not defs.get(fn) or file in defs[fn]:
            return frame
        return fn, max(sorted(defs[fn]), key=lambda f: votes[(fn, f)]), line

    return {o: [fix(f) for f in chain] for o, chain in chains.items()}


# ------------------------------------------------------------------ parts
#: a frame's part by its file, and by function where a file holds more than one part; None:
#: the frame's own instructions go to its caller's part (helpers that serve several parts)
SLOTS, GEOMETRY = "contact slots (slots.py: manifold, classify, changed_at)", "contact geometry (contacts.py, load.py)"
LAW, FRICTION = "contact law (normal force, D^1.5, D^0.25)", "friction (belt_friction, coulomb)"
DRIVE, EVENTS = "drive (drive.py drive_angle)", "events: candidates and location (events.py, search.py)"
PEAKS, BOOKS, DENSE = "peaks and tracked quantities (peaks.py)", "books (books.py)", "dense output (rk.py dense_coeffs, dense_eval)"
LOOP = "integrator: loop and step control (driver.py, rk.py)"
M, S, K = "fencesweep/model/", "fencesweep/model/scenes/", "fencesweep/kernel/"
FILE_PARTS = {
    S + "cycle/slots.py": SLOTS, S + "contacts.py": GEOMETRY, S + "load.py": GEOMETRY, M + "contact.py": LAW,
    M + "drive.py": DRIVE, S + "cycle/rhs.py": "right-hand side (rhs.py: equations, contact sums)",
    S + "cycle/events.py": EVENTS, S + "cycle/peaks.py": PEAKS, S + "cycle/books.py": BOOKS,
    S + "cycle/run.py": "step handling (run.py: accept, move_on, step and tolerances)",
    S + "stream.py": "cycle set-up (stream.py)", K + "driver.py": LOOP, K + "rk.py": "integrator: stages (rk.py)",
    K + "search.py": None,
}
FUNCTION_PARTS = {
    **{(S + "contacts.py", name): LAW for name in ("corner_fence_force", "corner_rail_force", "tip_edge_force",
                                                   "damping_power", "friction_power", "next_code")},
    (M + "contact.py", "belt_friction"): FRICTION, (M + "contact.py", "coulomb"): FRICTION,
    (S + "load.py", "outcome_margin"): EVENTS, (S + "load.py", "initial_state"): BOOKS,
    (K + "rk.py", "dense_coeffs"): DENSE, (K + "rk.py", "dense_eval"): DENSE, (K + "rk.py", "error_norm"): LOOP,
    (K + "rk.py", "next_step"): LOOP, (S + "cycle/rhs.py", "fence_state"): DRIVE,
    **{(K + "search.py", name): EVENTS for name in ("cycle_find_change", "cycle_find_outcome", "cycle_find_crossing",
                                                    "cycle_min_gap")},
    **{(K + "search.py", name): PEAKS for name in ("cycle_peak_of", "cycle_find_touch")}}
#: functions that only hold the others (the loop, the step's handling, the cycle's set-up): their
#: frames do not make their instructions count towards their part's inclusive share, which would
#: otherwise be nearly everything
CONTAINERS = {(S + "cycle/run.py", "run"), (S + "cycle/run.py", "accept"), (K + "driver.py", "cycle_loop"),
              (K + "driver.py", "integrate")}
#: libraries the kernel calls, by the callee's name
LIBRARY_PARTS = (("sincos", "libm: sin, cos (sincos)"), ("sin", "libm: sin, cos (sincos)"),
                 ("cos", "libm: sin, cos (sincos)"), ("pow", "libm: pow"), ("numba_pow", "libm: pow"),
                 ("memcpy", "libc: memcpy, memset"), ("memset", "libc: memcpy, memset"),
                 ("NRT_", "Numba runtime (NRT)"))
OTHER_LIBRARY = "other library calls"
UNKNOWN = "(no source line)"


def part_of(frame: Frame):
    """The frame's part, "" for a frame of Numba's own (its caller's part), None for a helper
    (its caller's part too)."""
    fn, file, _ = frame
    if not file.startswith("fencesweep/"):
        return ""
    return FUNCTION_PARTS.get((file, fn), FILE_PARTS.get(file, f"other ({file})"))


def library_part(name: str) -> str:
    base = name.split("@")[0].lstrip("_").replace("ieee754_", "")
    for key, part in LIBRARY_PARTS:
        if base.startswith(key):
            return part
    return OTHER_LIBRARY


def own_frame(chain: list[Frame]):
    """The innermost frame whose own part counts (a package frame that is not a helper)."""
    for frame in chain:
        if part_of(frame):
            return frame
    return None


class Profile:
    """Callgrind's counts on the object's code, attributed to parts (module docstring, step 4)."""

    def __init__(self, obj: Path, funcs: dict, collected: int, self_cost: dict, calls: list):
        data = obj.read_bytes()
        self.base, self.size = text_base(funcs), len(code_section(data))
        self.collected = collected
        starts = sorted((off, off + size, name) for name, (off, size) in elf_functions(data).items())
        self.functions = [s for s in starts if "fencesweep" in s[2]]
        where = {addr: name for name, (addr, _, _) in funcs.items()}  # weak ones resolved elsewhere too
        def inside(a):
            return a is not None and self.base <= a < self.base + self.size

        self.items = []  # (offset, library part or None, cost, calls)
        self.edges = []  # (site offset, callee function, calls, inclusive cost)
        self.entered = 0  # inclusive cost of calls into the code from outside it
        for addr, cost in self_cost.items():
            if inside(addr):
                self.items.append((addr - self.base, None, cost, 0))
        for site, target, n, cost, callee in calls:
            if inside(site) and inside(target):
                self.edges.append((site - self.base, self.function_at(target - self.base), n, cost))
            elif inside(site):
                name = where.get(target, callee or "?")
                self.items.append((site - self.base, library_part(name), cost, n))
            elif inside(target):
                self.entered += cost
        offsets = sorted({o for o, *_ in self.items} | {o for o, *_ in self.edges})
        self.chains = normal_files(symbolize(obj, offsets))
        self.kernel = sum(c for _, _, c, _ in self.items)
        self._context = {}

    def function_at(self, offset: int) -> str:
        for lo, hi, name in self.functions:
            if lo <= offset < hi:
                return name
        return "?"

    def keys(self, chain: list[Frame]) -> set:
        """What an instruction of this chain counts towards: its frames' functions and parts."""
        out = set()
        for frame in chain:
            part = part_of(frame)
            if part:
                out.add(frame[:2])
                if frame[:2] not in CONTAINERS and not frame[1].endswith("/stream.py"):
                    out.add(part)
        return out

    def context(self, function: str) -> dict:
        """{key: share of the function's cost that runs under it}: its callers' chains, in
        proportion to each call site's inclusive count (module docstring, step 4)."""
        if function in self._context:
            return self._context[function]
        self._context[function] = {}  # a cycle (none expected) counts as no context
        into = [(o, n, c) for o, f, n, c in self.edges if f == function]
        total = sum(c for _, _, c in into)
        ctx = collections.Counter()
        for site, _, cost in into:
            w = cost / total
            own = self.keys(self.chains[site])
            for key in own:
                ctx[key] += w
            for key, share in self.context(self.function_at(site)).items():
                if key not in own:
                    ctx[key] += w * share
        self._context[function] = dict(ctx)
        return self._context[function]

    def spread(self, keys: set, function: str, cost: float, into: collections.Counter) -> None:
        """Add cost to every key of its chain and, in proportion, to those of its function's callers."""
        for key in keys:
            into[key] += cost
        for key, share in self.context(function).items():
            if key not in keys:
                into[key] += cost * share

    def attribute(self):
        """own: {part: cost}; inclusive: {key: cost}; by_function: {(function, file): cost};
        library: {part: [cost, calls, {caller frame: calls}, {caller frame: cost}, inclusive]}."""
        own, inclusive, by_function = collections.Counter(), collections.Counter(), collections.Counter()
        library = {}
        for offset, lib, cost, n in self.items:
            chain = self.chains[offset]
            keys = self.keys(chain)
            frame = own_frame(chain)
            if lib is not None:
                own[lib] += cost
                entry = library.setdefault(lib, [0, 0, collections.Counter(), collections.Counter(),
                                                 collections.Counter()])
                entry[0] += cost
                entry[1] += n
                entry[2][frame[:2] if frame else UNKNOWN] += n
                entry[3][frame[:2] if frame else UNKNOWN] += cost
                keys.add(lib)
                self.spread(keys, self.function_at(offset), cost, entry[4])
            else:
                own[part_of(frame) if frame else UNKNOWN] += cost
                if frame is not None:
                    by_function[frame[:2]] += cost
            self.spread(keys, self.function_at(offset), cost, inclusive)
        return own, inclusive, by_function, library


# ------------------------------------------------------------------ time (perf)
def run_perf(cache: Path, obj: Path, seconds: float, work: Path, cpu):
    """Sample the worker's loop (the build in `cache`, compiled for `cpu`, None: this machine's)
    with perf for `seconds`: {code offset:
    samples}, {library part: samples}, samples elsewhere, (steps, rejects) of one pass."""
    proc = subprocess.Popen(_worker_cmd("loop", obj), env=_env(cache, cpu), cwd=ROOT, stdin=subprocess.PIPE,
                            stdout=subprocess.PIPE, text=True)
    lines = []
    for line in proc.stdout:
        if line.startswith("READY"):
            break
        lines.append(line)
    funcs, steps = parse_worker("".join(lines))
    base, size = text_base(funcs), len(code_section(obj.read_bytes()))
    data = work / "perf.data"
    try:
        subprocess.run(["perf", "record", "-e", "cpu-clock", "-F", "10000", "-p", str(proc.pid), "-o", str(data),
                        "--", "sleep", str(seconds)], check=True, capture_output=True)
    finally:
        proc.stdin.close()
        proc.wait()
    out = subprocess.run(["perf", "script", "-i", str(data), "-F", "ip,sym,dso"], capture_output=True, text=True,
                         check=True).stdout
    jit, lib, elsewhere = collections.Counter(), collections.Counter(), 0
    for line in out.splitlines():
        m = re.match(r"\s*([0-9a-f]+)\s+(.*?)\s+\((.*)\)\s*$", line)
        if not m:
            continue
        ip, sym, dso = int(m.group(1), 16), m.group(2), m.group(3)
        if base <= ip < base + size:
            jit[ip - base] += 1
        elif ("libm" in dso or "libc" in dso or "helperlib" in dso) and library_part(sym) != OTHER_LIBRARY:
            lib[library_part(sym)] += 1
        else:
            elsewhere += 1
    return jit, lib, elsewhere, steps


def time_shares(obj: Path, jit: dict, lib: dict, prof: Profile):
    """Samples by part and by function ("own", as the instructions' columns), and inclusive: a
    sample in the code with its chain and its function's callers as callgrind counted them (the
    builds' functions have the same names), a library's samples spread over its callers as its
    instructions are."""
    chains = normal_files(symbolize(obj, sorted(jit)))
    functions = sorted((off, off + size, name) for name, (off, size) in elf_functions(obj.read_bytes()).items())
    own, by_function, inclusive = collections.Counter(lib), collections.Counter(), collections.Counter()
    library = prof.attribute()[3]
    for offset, n in jit.items():
        frame = own_frame(chains[offset])
        own[part_of(frame) if frame else UNKNOWN] += n
        if frame:
            by_function[frame[:2]] += n
        function = next((name for lo, hi, name in functions if lo <= offset < hi), "?")
        prof.spread(prof.keys(chains[offset]), function, n, inclusive)
    for part, n in lib.items():
        if part in library:
            for key, cost in library[part][4].items():
                inclusive[key] += n * cost / library[part][0]
    return own, by_function, inclusive


# ------------------------------------------------------------------ the page
def _pct(x: float, total: float) -> str:
    return f"{100 * x / total:.1f} %"


def _row(*cells) -> str:
    return md_row(cells)


def _table(title: str, intro: str, cols: list[str]) -> list[str]:
    """A section's head and its table's (common.md_table: a column ending in ">" right-aligned)."""
    return ["", f"## {title}", "", *([intro, ""] if intro else []), *md_table(cols)]


class Page:
    """The page's numbers: the profile's attribution and the units (cycles, accepted steps)."""

    def __init__(self, prof: Profile, state: dict, timing: dict):
        self.prof, self.state, self.timing = prof, state, timing
        self.own, self.inclusive, self.by_function, self.library = prof.attribute()
        self.kernel = prof.kernel
        self.cycles = N_SCENES * state["passes"]
        self.steps, self.rejects = (x * state["passes"] for x in state["steps"])
        self.callees = collections.defaultdict(lambda: [0, 0, collections.Counter()])  # calls, cost, callers
        for site, callee, n, cost in prof.edges:
            entry, frame = self.callees[short_name(callee)], own_frame(prof.chains[site])
            entry[0], entry[1] = entry[0] + n, entry[1] + cost
            entry[2][frame[0] if frame else "?"] += n

    def pct(self, x: float) -> str:
        return _pct(x, self.kernel)

    def head(self) -> list[str]:
        s, prof = self.state, self.prof
        return [
            "# Where a warm cycle's instructions go, by part", "",
            f"Regenerate: `python benchmarks/profile_parts.py{' --perf 10' if self.timing else ''}` (~3 min on 2 cores; "
            "how, and what the numbers can and cannot say: its docstring).", "",
            f"Counted: the warm cycle kernel, `run_cycles`, on the main job's fixed sample of {N_SCENES} scenes "
            f"(benchmarks/asv_bench `main_job_sample`), {s['passes']} pass{'es' if s['passes'] > 1 else ''} under "
            f"callgrind: {prof.collected:,} instructions, {self.kernel:,} of them ({_pct(self.kernel, prof.collected)}) "
            "in the kernel's code and the library functions it calls, the rest Python's calls of the entry point. "
            f"**{self.kernel / self.cycles:,.0f} instructions a cycle, {self.steps / self.cycles:.1f} accepted steps a "
            f"cycle ({self.rejects / self.cycles:.1f} rejected), {self.kernel / self.steps:,.0f} instructions an "
            "accepted step.**", "",
            f"The code counted is compiled for the CPU valgrind emulates ({s['cpu'][0]}: AVX2, no AVX-512), as "
            "instructions.py's counts are; the production build on this machine uses AVX-512. " + " ".join(s["checks"]),
        ]

    def parts(self) -> list[str]:
        top = collections.defaultdict(list)
        for (fn, file), cost in self.by_function.most_common():
            top[part_of((fn, file, 0))].append((fn, cost))
        lines = _table("By part", (
            "\"own\": each instruction to the innermost package function it was inlined from (Numba's helpers and "
            "library calls to the line that called them, libm's own rows aside); the rows add up to 100 %. "
            "\"inclusive\": every instruction under a function of the part, however deep (the parts overlap; "
            "\"—\": a part that holds the others, the loop and the step's handling, whose inclusive share is "
            "nearly all). Per step: per accepted step (the work of rejected steps included)."
            + (" Time: the share of perf's cpu-clock samples (own, as the instructions), of the build counted and of "
               "the native (AVX-512) build, the production code; time shares moved by up to 3 points between runs on "
               "the shared 2-core machine (the contact law's square roots most), the instruction counts do not move."
               if self.timing else "")),
            ["part", "own>", "per cycle>", "per step>", "inclusive>", *(f"{name}>" for name in self.timing),
             "most of it (own)"])
        for part, cost in self.own.most_common():
            container = part.startswith(("step handling", "integrator: loop", "cycle set-up", "("))
            inc = "—" if container or part not in self.inclusive else self.pct(self.inclusive[part])
            most = ", ".join(f"{fn} {self.pct(c)}" for fn, c in top.get(part, [])[:4])
            if part in self.library:
                total, n = self.library[part][:2]
                most = f"{n / self.cycles:,.1f} calls a cycle, {total / max(1, n):,.0f} instructions a call"
            lines.append(_row(part, self.pct(cost), f"{cost / self.cycles:,.0f}", f"{cost / self.steps:,.0f}", inc,
                              *(_pct(t.get(part, 0), sum(t.values())) for t in self.timing.values()), most))
        return lines

    def libraries(self) -> list[str]:
        lines = _table("Library calls, by caller", "", ["function", "caller (innermost package function)",
                                                         "calls a cycle>", "calls a step>", "instructions a step>"])
        for part, (_, _, callers, costs, _) in sorted(self.library.items(), key=lambda kv: -kv[1][0]):
            for caller, k in callers.most_common(6):
                name = f"{caller[0]} ({Path(caller[1]).name})" if isinstance(caller, tuple) else caller
                lines.append(_row(part, name, f"{k / self.cycles:,.1f}", f"{k / self.steps:.2f}",
                                  f"{costs[caller] / self.steps:,.0f}"))
        lines += _table("Library calls, by path", "", ["function", "path (innermost first)", "calls a step>"])
        paths = collections.Counter()
        for offset, lib, _, n in self.prof.items:
            if lib is not None and lib.startswith("libm"):
                chain = [f[0] for f in self.prof.chains[offset] if f[1].startswith("fencesweep/")]
                paths[(lib, " < ".join(chain[:6]))] += n
        for (lib, path), n in paths.most_common(12):
            lines.append(_row(lib, path, f"{n / self.steps:.2f}"))
        return lines

    def functions(self) -> list[str]:
        lines = _table("Functions, by inclusive share", "Each function's instructions and those of everything it "
                       "calls (inlined or not), and its own.", ["function", "file", "inclusive>", "own>",
                                                                 "inclusive per step>"])
        funcs = [(k, v) for k, v in self.inclusive.items() if isinstance(k, tuple)]
        for (fn, file), cost in sorted(funcs, key=lambda kv: -kv[1])[:40]:
            lines.append(_row(fn, file.removeprefix("fencesweep/"), self.pct(cost),
                              self.pct(self.by_function.get((fn, file), 0)), f"{cost / self.steps:,.0f}"))
        return lines

    def calls(self) -> list[str]:
        lines = _table("Calls of the functions that are not inlined", "The functions left as functions of their own "
                       "(kernel/jit.py `kernel()` without inline, the specialised templates): how often a step calls "
                       "each, and what a call costs with all it calls.", ["function", "calls a step>",
                                                                          "instructions a call>", "inclusive>",
                                                                          "called from (calls a step)"])
        for name, (n, cost, callers) in sorted(self.callees.items(), key=lambda kv: -kv[1][1]):
            if n / self.steps >= 0.01:
                where = ", ".join(f"{c} {k / self.steps:.2f}" for c, k in callers.most_common(3))
                lines.append(_row(name, f"{n / self.steps:.2f}", f"{cost / n:,.0f}", self.pct(cost), where))
        return lines

    def share(self, key, time_functions=None) -> str:
        """A function's or part's inclusive share: of instructions, and of time when sampled."""
        text = self.pct(self.inclusive.get(key, 0))
        if time_functions:
            t_inc = time_functions[1]
            text += f" ({_pct(t_inc.get(key, 0), sum(self.timing['time, native build'].values()))} of time)"
        return text

    def suggestions(self, time_functions) -> list[str]:
        """What the profile suggests to cut first: the largest shares, with what makes them."""
        f = self.share
        key = {}  # a function's name: its (name, file) of the largest inclusive share
        for k in sorted((k for k in self.inclusive if isinstance(k, tuple)), key=lambda k: self.inclusive[k]):
            key[k[0]] = k
        per = lambda name: self.callees[name][0] / self.steps  # noqa: E731  calls a step
        cost = lambda name: self.callees[name][1] / max(1, self.callees[name][0])  # noqa: E731  a call
        sincos = self.library.get("libm: sin, cos (sincos)", [0, 0, collections.Counter()])
        frame_calls = {c[0]: n / self.steps for c, n in sincos[2].items() if isinstance(c, tuple)}
        law = ("contact law (normal force, D^1.5, D^0.25)", "friction (belt_friction, coulomb)")
        own_t = self.timing.get("time, native build", {})
        t_total = sum(own_t.values()) or 1
        out = ["", "## What the profile suggests to cut first", ""]
        if "cycle_find_change" in key and per("event_state"):
            bisected = self.callees["mask_changed"][2]["cycle_find_change"] / self.steps
            out.append(
                f"1. **Event location** (search.bisect in find_event): {f(key['cycle_find_change'], time_functions)}. "
                f"Each located event bisects the step to EVENT_TOL (1e-12 s): {bisected / per('event_state'):.0f} "
                f"evaluations of mask_changed an event ({bisected:.2f} a step, {per('event_state'):.2f} events a "
                f"step), each {cost('mask_changed'):,.0f} instructions: the dense output, the frame (drive_angle and "
                f"two sincos) and the whole manifold ({cost('manifold'):,.0f}). A bracket search that converges "
                "faster than bisection, on the continuous quantity whose sign makes the change (the slot's gap or "
                "force; Illinois or Brent, bisection kept as the safeguard), would take a fraction of the evaluations.")
        if sincos[1]:
            stages = frame_calls.get("rhs", 0) + frame_calls.get("contact_sum", 0)
            out.append(
                f"2. **sin and cos** (libm sincos): {self.pct(sincos[0])} of instructions"
                + (f", {_pct(own_t.get('libm: sin, cos (sincos)', 0), t_total)} of time" if own_t else "")
                + f"; {sincos[1] / self.steps:.1f} calls a step, {sincos[0] / sincos[1]:.0f} instructions a call. "
                f"{stages:.1f} of them are the frame of every right-hand side (cos, sin of alpha in rhs, of phi in "
                f"contact_sum: ~{per('cycle_step') * 6:.1f} evaluations a step), "
                f"{frame_calls.get('frame_at', 0):.1f} the frame of the event searches' points (frame_at: alpha and "
                f"phi again), {frame_calls.get('min_corner_x', 0):.1f} the escape test at the step's end "
                "(min_corner_x), whose phi the FSAL stage's frame in aux already holds. Within a step alpha and phi "
                "move by little: cos and sin at a stage from those at the step's start by the angle-addition formula "
                "with a short series in the increment would replace most calls (the last bits of results change).")
        if "drive_angle" in key:
            evaluations = 6 * per("cycle_step") + frame_calls.get("frame_at", 0) / 2 + per("quantities")
            out.append(
                f"3. **The drive** (drive_angle): {f(key['drive_angle'], time_functions)}, "
                f"~{self.inclusive[key['drive_angle']] / self.steps / evaluations:.0f} instructions an evaluation, "
                f"~{evaluations:.1f} a step: one in every right-hand side (fence_state) and every frame_at. "
"DOPRI5's sixth stage and its seventh (the FSAL stage) are both at t + h (c6 = c7 = 1), so the drive "
                "there is evaluated twice a step; the table's cubic Hermite interpolation (hermite_basis, then eight "
                "products) could read per-interval polynomial coefficients (Horner) instead.")
        if own_t:
            out.append(
                "4. **The contact law and friction, in time**: "
                + " + ".join(_pct(own_t.get(part, 0), t_total) for part in law)
                + " of time for " + " + ".join(self.pct(self.own.get(part, 0)) for part in law)
                + " of instructions: kelvin_force's D^1.5 = D sqrt(D) and D^0.25 = sqrt(sqrt(D)) are two dependent "
                "square roots, belt_friction has a square root and three divisions by it, coulomb a square root and "
                "a division. Dividing once (1 / s, then products) is a small cut; the square roots are the law's, "
                "so fewer force evaluations is the larger one.")
        if "dense_coeffs" in key:
            out.append(
                f"5. **Dense output** (dense_coeffs): {f(key['dense_coeffs'], time_functions)}: the coefficients "
                "of all 13 state components whenever a step needs any, though events and peaks read 8 (N_CTRL); "
                f"the other 5 are needed only at an event ({per('event_state'):.2f} a step).")
        out.append(
            f"\nThe step's handling costs more than the step: accept {f(key.get('accept'), time_functions)} against "
            f"{f(key.get('cycle_step'), time_functions)} for the step itself (its six stages, each a right-hand side). "
            "Instruction counts miss the latency of square roots and divisions (the contact law) and overcount "
            "`rep movsb` (libc memcpy: valgrind counts a byte as an instruction; here the 49.5 kB copy of p, the drive "
            "table included, that run_cycles makes once a cycle: ~1 % of instructions, no measurable time).")
        return out

    def time_table(self, time_functions) -> list[str]:
        if not time_functions:
            return []
        own, inclusive = time_functions
        t_total = sum(self.timing["time, native build"].values())
        lines = _table("Functions, by time (native build)", (
                 "perf's samples of the native build: by the innermost package function (own) and under each function "
                 "(inclusive), beside the instructions' shares (the build counted). A function with more time than "
                 "instructions holds long-latency instructions (square roots, divisions, loads that wait): a sample "
                 "lands on the instruction the core waits for."), ["function", "file", "time, own>", "instructions, own>",
                                                                   "time, inclusive>", "instructions, inclusive>"])
        rows = {k for k, _ in own.most_common(25)} | {k for k, v in inclusive.items()
                                                       if isinstance(k, tuple) and k not in CONTAINERS
                                                       and v / t_total > 0.03 and not k[1].endswith("stream.py")}
        for fn, file in sorted(rows, key=lambda k: -own.get(k, 0)):
            lines.append(_row(fn, file.removeprefix("fencesweep/"), _pct(own.get((fn, file), 0), t_total),
                              self.pct(self.by_function.get((fn, file), 0)), _pct(inclusive.get((fn, file), 0), t_total),
                              self.pct(self.inclusive.get((fn, file), 0))))
        return lines


def report(prof: Profile, state: dict, timing: dict, time_functions) -> str:
    page = Page(prof, state, timing)
    lines = [*page.head(), *page.suggestions(time_functions), *page.parts(), *page.libraries(), *page.calls(),
             *page.functions(), *page.time_table(time_functions)]
    return "\n".join(lines) + "\n"


# ------------------------------------------------------------------ main
def build(a, state: dict, work: Path, name: str, cpu, what: str) -> Path:
    """Compile run_cycles with line tables into work/cache-NAME, its object work/NAME.o (module docstring,
    step 1), and unless --no-check the same without them, whose code section must be the same (step 2)."""
    print(f"compiling the {name} build with line tables for {cpu[0] if cpu else 'this CPU'} ...", flush=True)
    obj = work / f"{name}.o"
    code = code_section(compile_object("compile", work / f"cache-{name}", obj, cpu))
    if not a.no_check:
        print("compiling it without them ...", flush=True)
        if code_section(compile_object("compile-plain", work / f"cache-{name}-plain", work / f"{name}-plain.o",
                                       cpu)) != code:
            raise SystemExit(f"{what}: the code compiled with line tables differs from the code without; the "
                             "profile would not be of the production code")
        state["checks"].append(f"{what}: its code section ({len(code):,} bytes) is byte for byte that of the same "
                               "compile without line tables.")
    return obj


def measure(a, work: Path) -> dict:
    """Compile, check, count and (with --perf) sample; what the page is made of, kept in
    work/state.json (--from reads it again)."""
    for cache in work.glob("cache*"):  # a kept folder's: compiled anew, or there is no object code to read
        shutil.rmtree(cache)
    cpu = valgrind_cpu()
    state = {"cpu": cpu, "passes": a.passes, "checks": [], "perf": {}}
    obj = build(a, state, work, "counted", cpu, "The build counted")
    print("counting under callgrind ...", flush=True)
    state["collected"], (state["funcs"], state["steps"]) = run_callgrind(work / "cache-counted", obj, a.passes,
                                                                         work / "callgrind.out", cpu)
    if a.perf:
        print(f"sampling it with perf for {a.perf:g} s ...", flush=True)
        state["perf"]["counted build"] = run_perf(work / "cache-counted", obj, a.perf, work, cpu)[:3]
        native = build(a, state, work, "native", None, "The native build, which perf samples")
        print(f"sampling it with perf for {a.perf:g} s ...", flush=True)
        state["perf"]["native build"] = run_perf(work / "cache-native", native, a.perf, work, None)[:3]
    (work / "state.json").write_text(json.dumps(state))
    return state


def analyse(state: dict, work: Path) -> str:
    prof = Profile(work / "counted.o", state["funcs"], state["collected"], *parse_callgrind(work / "callgrind.out"))
    if prof.entered != prof.kernel:
        raise SystemExit(f"the calls into the code ({prof.entered:,}) and what was attributed ({prof.kernel:,}) differ")
    timing, time_functions = {}, None
    for name, (jit, lib, elsewhere) in state["perf"].items():
        obj = work / ("counted.o" if name == "counted build" else "native.o")
        timing[f"time, {name}"], *time_functions = time_shares(obj, {int(k): v for k, v in jit.items()}, lib, prof)
        state["checks"].append(f"perf, {name}: {sum(timing[f'time, {name}'].values()):,} samples in the kernel and "
                               f"its library calls, {elsewhere:,} elsewhere (Python's loop).")
    return report(prof, state, timing, time_functions)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("?")[0] + "? (the docstring says how)")
    ap.add_argument("--passes", type=int, default=1, help="passes of the 60 scenes counted (default 1)")
    ap.add_argument("--no-check", action="store_true", help="skip the compiles without line tables")
    ap.add_argument("--perf", type=float, default=0.0, metavar="SECONDS",
                    help="also sample the time of the build counted and of the native build with perf, each this long")
    ap.add_argument("--out", type=Path, default=OUT, help="the page (default results/profile_parts.md)")
    ap.add_argument("--keep", type=Path, default=None, help="work in this folder and keep it (else a temporary one)")
    ap.add_argument("--from", dest="source", type=Path, default=None,
                    help="only write the page again, from a folder that --keep kept")
    ap.add_argument("--worker", help=argparse.SUPPRESS)
    ap.add_argument("--obj", type=Path, help=argparse.SUPPRESS)
    a = ap.parse_args()
    if a.worker:
        worker(a.worker, a.obj, a.passes)
        return
    if a.source is not None:
        page = analyse(json.loads((a.source / "state.json").read_text()), a.source)
    else:
        for tool in ("valgrind", "callgrind_control") + (("perf",) if a.perf else ()):
            if not shutil.which(tool):
                raise SystemExit(f"{tool} is needed")
        with tempfile.TemporaryDirectory() as tmp:
            work = a.keep or Path(tmp)
            work.mkdir(parents=True, exist_ok=True)
            page = analyse(measure(a, work), work)
    print(page)
    a.out.write_text(page)


if __name__ == "__main__":
    main()
