"""The step driver: the one accept/reject loop that every scene integrates with (in the spirit
of scipy.integrate._ivp's ivp.py: the method steps, the driver owns the loop and its stops, the
scene handles what happens at each accepted step).

    loop = integrator(step, accept, name)       # once per scene (kernel/jit.py specialise)
    t, h, why = loop(ctl, p, w, t, t_end, t_land, h)

steps (t, w.y) towards t_end with the scene's step (kernel/rk.py stepper) under error control. A step that would
pass t_land (a time a result is read at, e.g. t_c) is shortened to end on it exactly (t1 =
t_land, not the rounded t + h). A rejected step is retried shorter (kernel/numerics.py: SAFETY,
FAC_MIN); an accepted one goes to the scene's `accept(p, w, t, h, t1, err, h_next) -> (t,
h_next, stop)`: it locates the events inside the step, tracks its peaks, moves w.y on to the
new t (t1, the step's end, or an event before it) and may shorten the next step or stop the
loop. The stops, in one place:

  STOP_END        t reached t_end;
  STOP_SCENE      accept said stop (an outcome, a failed state);
  STOP_MAX_STEPS  numerics.MAX_STEPS attempted steps (w.count[C_STEPS] + w.count[C_REJECTS]);
  STOP_UNDERFLOW  a step shorter than h_floor max(1, t) would be needed.

`ctl` = (method, h_max, dt, h_floor): the method code, the largest step, the fixed step of RK4,
the step floor. The work tuple `w` has at least y, y1, tmp, K, aux, atol and rtol (the
tolerances, which the scene may change from step to step),
iw (the scene's integer state) and count (C_STEPS, C_REJECTS, C_ERR2: accepted and rejected
steps and the sum of the accepted steps' squared error norms, each times its rtol: the local
errors relative to the error scales, whatever tolerance each step had).
"""
from __future__ import annotations

from fencesweep.kernel import numerics as NU
from fencesweep.kernel import rk
from fencesweep.kernel.jit import kernel, specialise

STOP_END, STOP_SCENE, STOP_MAX_STEPS, STOP_UNDERFLOW = 0, 1, 2, 3
C_STEPS, C_REJECTS, C_ERR2, N_COUNT = 0, 1, 2, 3
#: t counts as having reached t_end within this fraction of max(1, t_end) [s]
END_TOL = 1e-12


@kernel(inline=True)
def reached(t, t_end):
    """Has t reached t_end (within END_TOL)?"""
    return t >= t_end - END_TOL * max(1.0, t_end)


@kernel(inline=True)
def rejected_step(h, err):
    """The step to retry after one rejected with error norm err (NaN: the state blew up)."""
    if err == err:
        return rk.next_step(h, err, NU.SAFETY, NU.FAC_MIN, 1.0)
    return NU.FAC_MIN * h


#: the scene's step and accept in the template `integrate`, bound by `integrator`
STEP = ACCEPT = None


def integrator(step, accept, name: str):
    """`integrate` with the scene's step and accept, compiled as the kernel function `name`."""
    return specialise(integrate, name, STEP=step, ACCEPT=accept)


def integrate(ctl, p, w, t, t_end, t_land, h):
    """Step towards t_end, landing on t_land (module docstring); returns (t, the next step, why
    it stopped). A template: STEP and ACCEPT are the scene's (`integrator`)."""
    method, h_max, dt, h_floor = ctl
    n = w.y.shape[0]
    while not reached(t, t_end):
        if w.count[C_STEPS] + w.count[C_REJECTS] >= NU.MAX_STEPS:
            return t, h, STOP_MAX_STEPS
        if method == rk.METHOD_RK4:
            h = dt
        h = min(h, h_max, t_end - t)
        lands = t < t_land and t + h >= t_land
        if lands:
            h = t_land - t
        err = STEP(method, t, w.y, h, p, w.iw, w.K, w.tmp, w.y1, w.aux, w.atol, w.rtol[0], n)
        if not (err <= 1.0):  # rejected (a NaN error too)
            h = rejected_step(h, err)
            w.count[C_REJECTS] += 1.0
            if h < h_floor * max(1.0, t):
                return t, h, STOP_UNDERFLOW
            continue
        w.count[C_STEPS] += 1.0
        e = err * w.rtol[0]  # the local error relative to the error scales at tolerance 1
        w.count[C_ERR2] += e * e
        h_next = rk.next_step(h, err, NU.SAFETY, NU.FAC_MIN, NU.FAC_MAX)
        t, h, stop = ACCEPT(p, w, t, h, t_land if lands else t + h, err, h_next)
        if stop:
            return t, h, STOP_SCENE
    return t, h, STOP_END
