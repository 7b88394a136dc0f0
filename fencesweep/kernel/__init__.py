"""The integrator contract and Numba's set-up: no physics here.

  jit.py       how kernel functions are compiled (one signature, IR for callers, templates)
  libraries.py the package's own code libraries (a kernel function's: IR only), so that Numba's
               own classes stay as they are
  cache.py     where compiled entry points are cached; first-run notice and compile lock
  locator.py   Numba's cache locator for the package's functions
  internals.py every private or internal name of Numba, numba-cuda and llvmlite kernel/ uses, in
               one list, each with what it is used for
  share.py     a first run's compile on two cores (a helper process and a cache of kernel IR)
  numerics.py  every tolerance and step bound of the engine, each with its reason
  rk.py        Runge-Kutta steps (DOPRI5, RK4), error norm, dense output, step controller
  search.py    event location (bisection) and peak finding (Brent) on a step's dense output
  driver.py    the one accept/reject step loop every scene integrates with
"""
import os

# Numba formats a message for every overload candidate it rejects while typing; with colorama
# installed each one set up and tore down colorama's terminal wrappers (5% of a cold compile).
# Read once, when Numba is first imported: set before any kernel module imports it.
os.environ.setdefault("NUMBA_DISABLE_ERROR_MESSAGE_HIGHLIGHTING", "1")
