"""The kernels' compile policy (fencesweep/jit.py): every compiled function of the kernel
modules runs without Numba's reference counting, but for the three that allocate a run's
work arrays; and a function under that policy cannot allocate."""
import importlib
import json
import subprocess
import sys

import numpy as np
import pytest
from numba.core.dispatcher import Dispatcher
from numba.core.errors import TypingError

from fencesweep.model import simulate as api
from fencesweep.kernel.jit import kernel

KERNEL_MODULES = ("kernel.integrate", "model.drive", "model.contact", "model.scenes.contacts", "model.scenes.load",
                  "model.scenes.cycle", "model.scenes.stream", "model.scenes.impact", "model.scenes.freefall")
ALLOCATING = {"stream_kernel", "cycle_kernel", "impact_kernel"}


def _dispatchers():
    for name in KERNEL_MODULES:
        mod = importlib.import_module(f"fencesweep.{name}")
        for attr, obj in vars(mod).items():
            if isinstance(obj, Dispatcher) and obj.__module__ == mod.__name__:
                yield f"{name}.{attr}", attr, obj


def test_every_kernel_function_runs_without_reference_counting_but_the_allocating_entry_points():
    seen = list(_dispatchers())
    assert len(seen) > 50
    for qual, attr, disp in seen:
        assert disp.targetoptions.get("_nrt") is (attr in ALLOCATING), qual
    assert ALLOCATING <= {attr for _, attr, _ in seen}


def test_a_kernel_function_that_allocates_does_not_compile():
    @kernel()
    def allocates(n):
        return np.zeros(n).sum()

    with pytest.raises(TypingError):
        allocates(3)


def test_loading_the_kernels_imports_neither_scipy_linalg_nor_cffi_nor_coverage():
    """jit.py answers Numba's BLAS probe "no" while Numba loads its NumPy support (the probe
    imports all of scipy.linalg, 0.27 s a process) and hides cffi and coverage, which no kernel
    uses; the kernels run the same without them."""
    here = api.simulate(case="small_far")  # compiles into the cache if it is not there
    unused = ["scipy.linalg", "cffi", "pycparser", "coverage"]
    code = ("import sys, json\nfrom fencesweep.model import simulate as api\nr = api.simulate(case='small_far')\n"
            f"print(json.dumps([[m for m in {unused!r} if m in sys.modules], r['peak_force']]))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    imported, peak = json.loads(out.stdout.strip().splitlines()[-1])
    assert imported == []
    assert peak == here["peak_force"]


def test_a_module_imported_already_is_not_hidden():
    from fencesweep.kernel.jit import _hidden

    with _hidden("json", "fencesweep_no_such_module"):
        assert sys.modules["json"] is json
        with pytest.raises(ImportError):
            import fencesweep_no_such_module  # noqa: F401
    assert "fencesweep_no_such_module" not in sys.modules
