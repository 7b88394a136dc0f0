"""The cycle's state, its work arrays and their index constants (compile-time constants for Numba).

State y (N_STATE = 13):
  0-5  load x, y, phi, x', y', omega                       (docs/model.md §1)
  6-7  fence alpha, alpha'                                  (§3; alpha_w itself when kinematic)
  8    damper energy  int B2 (alpha_w' - alpha')^2 dt       (§11, read at t_c)
  9    contact energy int sum (N - N_el) D' dt              (§11)
  10   drive work     int T_lever alpha_w' dt (rigid: -tau alpha_w')
  11   belt work      int (F . v + M omega) dt
  12   contact friction dissipation int sum -f w dt
The energies are quadratures of the first 8 components; all 13 are under error control (the
right-hand side, the events and the peaks read only the first N_CTRL = 8: a step's stages form
only those, its solution all 13).

Integer work vector iw: the corners' sides sigma_j (§5.1), the code of each contact slot
(contacts.py: APART / PUSH / CLIPPED), the fence's manifold (its axis, docs/model.md (5.7)), the fence mode, whether the load is on
the belt and whether it rides the belt in closed form.

`Work` is the tuple of a run's work arrays, allocated once by the entry point (stream.py) and
passed to the functions that need several of them.
"""
from __future__ import annotations

from collections import namedtuple

N_STATE = 13
N_CTRL = 8  # components that the right-hand side, events and peaks read (the energies are not)
# integer work vector
IW_CODE = 4  # 4 .. 13: slot codes (contacts.N_SLOTS)
IW_EDGE = 14  # the fence's manifold: its tag (slots.manifold)
IW_MODE = 15
IW_LOAD = 16
IW_RIDE = 17
N_IW = 18
FM_KELVIN, FM_KINEMATIC, FM_FREE = 0, 1, 2
# aux outputs of the right-hand side
AX_NF, AX_NR, AX_TAU, AX_DMAX, AX_FX, AX_FY, AX_TQ, AX_PDISS, AX_PFRIC = 0, 1, 2, 3, 4, 5, 6, 7, 8
# ... and the frame the contacts were evaluated in (frame_at's values; AX_FRAME 1 when set),
# which classify reuses at the end of a step instead of computing it again
AX_CA, AX_SA, AX_DAL, AX_CPHI, AX_SPHI, AX_FRAME, N_AUX = 9, 10, 11, 12, 13, 14, 15
# ... and, after the N_AUX that each right-hand side clears, the last angles of the fence and the
# load it took sines and cosines of exactly (kernel/trig.py cos_sin_near: angle, cos, sin), the
# last drive it evaluated (rhs.drive_once: t, alpha_w, alpha_w') and the drive at the step's start
# (rhs.keep_drive: the same three)
AX_TRIG_AL, AX_TRIG_PHI, AX_DRIVE, AX_KEPT, N_AUX_ALL = 15, 18, 21, 24, 27
# tracked maxima (docs/model.md §11)
Q_NF, Q_NR, Q_DEFL, Q_ALPHA, N_Q = 0, 1, 2, 3, 4
N_RISING = N_Q + 1  # Work.rising: one per quantity and one more (a shape: a constant, not an expression)
N_DENSE = 8  # rows of Work.Q
# rows of Work.qv: the quantities at the step's start and end, two samples inside it, a scratch
# row, where the step's maxima lie and the quantities' rates over the last step (peaks.track_maxima)
QV_0, QV_1, QV_A, QV_B, QV_S, QV_THETA, QV_RATE, N_QV = 0, 1, 2, 3, 4, 5, 6, 7
# trajectory columns
TRAJ_COLUMNS = ("t", "x", "y", "phi", "vx", "vy", "omega", "alpha", "alpha_w", "alpha_dot",
                "N_fence", "N_rail", "M_fence", "stage",
                "E_damper", "E_contact", "W_drive", "W_belt", "E_friction")
TRAJ_UNITS = ("s", "m", "m", "rad", "m/s", "m/s", "rad/s", "rad", "rad", "rad/s", "N", "N", "N m", "-",
              "J", "J", "J", "J", "J")
N_TRAJ = len(TRAJ_COLUMNS)
# run accumulators (float vector `acc`); the step counts are the driver's (Work.count)
# (A_TOUCH: 1 while the load touches the fence, books.touching; A_ONSET: the instant the fence's
# force first left 0 in the run)
(A_T_FIRST, A_T_LOSS, A_N_IMPACTS, A_DMAX, A_OUTCOME, A_STATUS, A_T_EXIT, A_X_EXIT, A_PHI_EXIT,
 A_E_CONTACT, A_RESID, A_RESID_AMP, A_E_DAMPER, A_EXITED, A_QMAX, A_STAGE, A_TOUCH, A_ONSET, N_ACC) = (
    0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 14 + N_Q, 14 + N_Q + 5, 14 + N_Q + 6, 14 + N_Q + 7)

#: a run's work arrays (allocated by stream.run, the one list of their shapes)
Work = namedtuple("Work", (
    "y",       # (N_STATE,) the state at the step's start
    "y1",      # (N_STATE,) the state at its end (or at the event that ends it)
    "tmp",     # (N_STATE,) a stage's state; a point of the dense output
    "dy",      # (N_STATE,) a right-hand side evaluated off the step
    "K",       # (N_STAGES, N_STATE) the step's stages
    "Q",       # (8, N_STATE) Q[:4] the step's dense output; Q[4:] a step to a release (events.release_state)
    "qok",     # (1,) int: Q[:4] holds the step's dense output: 0 not yet, 1 of N_CTRL components, 2 all (events.ensure_dense)
    "aux",     # (N_AUX_ALL,) forces of the last right-hand side (of f(t1, y1) after a step)
    "auxs",    # (N_AUX_ALL,) the searches' own: aux keeps f(t1, y1)'s forces
    "iw",      # (N_IW,) int: the integer state (module docstring)
    "codes1",  # (N_SLOTS,) int: the slots' codes at the step's end
    "tags1",   # (N_SLOTS,) int: their sides / the tip's edge there
    "g0",      # (N_SLOTS,) gaps at the step's start
    "r0",      # (N_SLOTS,) gap rates at the step's start
    "g1",      # (N_SLOTS,) gaps at its end
    "r1",      # (N_SLOTS,) gap rates at its end
    "qv",      # (N_QV, N_Q) tracked quantities (rows QV_*)
    "acc",     # (N_ACC,) the run's accumulators (A_*)
    "atol",    # (N_STATE,) absolute tolerances of the next step (run.set_tolerance)
    "atol0",   # (N_STATE,) the run's absolute tolerances (books.error_scales)
    "rtol",    # (1,) the relative tolerance of the next step
    "rising",  # (N_Q + 1,) per quantity: rising at the step's start; last: judge it anew
    "Ks",      # (N_STAGES, N_STATE) a step off the main one (to a peak, to a release)
    "ys",      # (N_STATE,) that step's end
    "count",   # (driver.N_COUNT,) the driver's step counts
    "traj",    # (rows, N_TRAJ) the trajectory, as many rows as fit (0 rows: none kept)
    "row",     # (1,) int: trajectory rows produced (counts on past traj's capacity)
    "pk",      # (len(p),) the parameters of the cycle running (a stream's p with that cycle's load)
))
