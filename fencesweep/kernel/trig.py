"""Sine and cosine of an angle near one already evaluated: the right-hand side's frame
(model/scenes/cycle/rhs.py) takes cos and sin of the fence's and the load's angle at every stage
of every step, and within a step they move by little (kernel/numerics.py TRIG_NEAR says why)."""
from __future__ import annotations

import math

from fencesweep.kernel import numerics as NU
from fencesweep.kernel.jit import kernel


@kernel(inline=True)
def one_minus_cos_sin(d):
    """(1 - cos d, sin d) by their Taylor series, for |d| <= TRIG_NEAR (the next terms, d^10 / 10!
    and d^11 / 11!, below 1e-18 there)."""
    d2 = d * d
    omc = d2 * (0.5 - d2 * (1.0 / 24.0 - d2 * (1.0 / 720.0 - d2 * (1.0 / 40320.0))))
    sd = d * (1.0 - d2 * (1.0 / 6.0 - d2 * (1.0 / 120.0 - d2 * (1.0 / 5040.0 - d2 * (1.0 / 362880.0)))))
    return omc, sd


@kernel(inline=True)
def cos_sin_near(x, base, k):
    """(cos x, sin x) with base[k:k + 3] = (b, cos b, sin b) the last angle evaluated exactly: by
    cos(b + d) = cos b - (cos b (1 - cos d) + sin b sin d), sin(b + d) = sin b - (sin b (1 - cos d)
    - cos b sin d) while |d| = |x - b| <= TRIG_NEAR; else by libm, and x becomes b. A base whose
    cos b and sin b are both 0 holds no angle (zeroed, or forget_angle)."""
    d = x - base[k]
    if abs(d) <= NU.TRIG_NEAR and (base[k + 1] != 0.0 or base[k + 2] != 0.0):
        omc, sd = one_minus_cos_sin(d)
        cb = base[k + 1]
        sb = base[k + 2]
        return cb - (cb * omc + sb * sd), sb - (sb * omc - cb * sd)
    c = math.cos(x)
    s = math.sin(x)
    base[k] = x
    base[k + 1] = c
    base[k + 2] = s
    return c, s


@kernel(inline=True)
def forget_angle(base, k):
    """No angle evaluated yet in base[k:k + 3]: the next cos_sin_near there calls libm."""
    base[k + 1] = 0.0
    base[k + 2] = 0.0
