"""Index layout of the float64 parameter vector `p` that every compiled kernel reads.

Module-level integers are compile-time constants for Numba. `prepare.prepare` fills the
vector from a resolved parameter dict (docs/model.md §12) plus derived constants. It holds only
what a kernel reads: a §12 value that enters only through a derived one (k1, k_lin and e
through KC and CD, mu1 through FMAX and MMAX, m2 through I2, coupler_ratio through the drive
table, w as the impact kernel's argument, step_factor through TOL and DT) has no slot.
"""

# --- docs/model.md §12, in its order ---
V = 0
PMAX = 1
MU2 = 2
LL = 3  # load length L
AA = 4  # load width A
M1 = 5
DP = 6
RS = 7
PHI0 = 8
LAW = 9  # 0 hertz, 1 linear
FL = 10  # fence length l
I2 = 11
B2 = 12
K2 = 13
DRIVE = 14  # 0 flexible, 1 rigid, 2 free
TC = 15
SWING = 16
PROFILE = 17  # 0 crank_rocker, 1 harmonic
H = 18
DAPERM = 19
R = 20
EPSV = 21
TMAX = 22
# --- derived ---
I1 = 23  # load inertia m1 (L^2 + A^2)/12
KC = 24  # stiffness of the active law: k1 (hertz) or k_lin (linear)
CD = 25  # damping coefficient of the active law: q sqrt(m1 k1) (hertz) or b_lin (linear)
FMAX = 26  # mu1 m1 g
MMAX = 27  # mu1 m1 g rho_bar
RHO = 28  # M_max / F_max
FFORCE = 29  # free-fall reference peak force (docs/model.md §7)
DAW_MAX = 30  # max |d alpha_w / dt| (the velocity scale of the error control)
TAB_N = 31  # number of intervals of the crank-rocker table (0 for the harmonic profile)
OMEGA_C = 32  # 2 pi / t_c, the crank's angular speed [rad/s]
TAB_RATE = 33  # TAB_N / t_c: table intervals per second (drive.drive_angle multiplies, not divides)
TAB_H = 34  # 2 pi / TAB_N, the crank angle of one table interval [rad] (1 for the harmonic profile)
# --- numerics (numerics.py; filled by prepare.prepare) ---
METHOD = 35  # rk.METHOD_DOPRI5 or rk.METHOD_RK4
TOL = 36  # local error tolerance (numerics.TOL x step_factor^5, floored)
DT = 37  # fixed step of the RK4 baseline [s]
H_MAX = 38  # largest step [s]
SNAP = 39  # slip [m/s] under which a load without contacts rides the belt in closed form
# --- the crank-rocker's geometry (docs/model.md (2.1), (2.5)), in a p without the table only (a GPU
# thread's, TAB_N = 0), which solves (2.2)-(2.6) at each time instead (drive.drive_angle); else 0 ---
CR_A, CR_B, CR_D, CR_TH0, CR_B0 = 40, 41, 42, 43, 44  # a, b, d, theta0, beta0
N_P = 45  # length of the header; the crank-rocker table follows it (drive.py)

# law / drive / profile codes
LAW_HERTZ, LAW_LINEAR = 0, 1
DRIVE_FLEXIBLE, DRIVE_RIGID, DRIVE_FREE = 0, 1, 2
PROFILE_CRANK_ROCKER, PROFILE_HARMONIC = 0, 1

G = 9.81  # m/s^2, docs/model.md §6


# --- one load of a stream (docs/model.md §14): the entries of p that change with the load, in the
# order of a row of the kernel's `loads` table (setup.load_table); the rest of p is the scene's ---
LOAD_SLOTS = (LL, AA, M1, DP, RS, PHI0, I1, KC, CD, FMAX, MMAX, RHO, FFORCE)
N_LOAD = len(LOAD_SLOTS)
