"""Index layout of the float64 parameter vector `p` that every compiled kernel reads.

Module-level integers are compile-time constants for Numba. `setup.prepare` fills the
vector from a resolved parameter dict (MODEL.md §12) plus derived constants.
"""

# --- MODEL.md §12, in its order ---
V = 0
PMAX = 1
MU1 = 2
MU2 = 3
LL = 4  # load length L
AA = 5  # load width A
M1 = 6
DP = 7
RS = 8
PHI0 = 9
E = 10
K1 = 11
LAW = 12  # 0 hertz, 1 linear
KLIN = 13
FL = 14  # fence length l
M2 = 15
I2 = 16
B2 = 17
K2 = 18
DRIVE = 19  # 0 flexible, 1 rigid, 2 free
TC = 20
SWING = 21
PROFILE = 22  # 0 crank_rocker, 1 harmonic
CRATIO = 23
H = 24
DAPERM = 25
R = 26
W = 27
EPSV = 28
TMAX = 29
STEPF = 30
# --- derived ---
I1 = 31  # load inertia m1 (L^2 + A^2)/12
KC = 32  # stiffness of the active law: k1 (hertz) or k_lin (linear)
CD = 33  # damping coefficient of the active law: q sqrt(m1 k1) (hertz) or b_lin (linear)
FMAX = 34  # mu1 m1 g
MMAX = 35  # mu1 m1 g rho_bar
RHO = 36  # M_max / F_max
CRA = 37  # crank length a (rocker c = 1)
CRB = 38  # coupler length b
CRD = 39  # ground length d
TH0 = 40  # crank angle of minimum rocker angle
BETA0 = 41  # minimum rocker angle
FFORCE = 42  # free-fall reference peak force (MODEL.md §7)
DAW_MAX = 43  # max |d alpha_w / dt| (the velocity scale of the error control)
TAB_N = 44  # number of intervals of the crank-rocker table (0 for the harmonic profile)
# --- numerics (numerics.py; filled by setup.prepare) ---
METHOD = 45  # integrate.METHOD_DOPRI5 or METHOD_RK4
TOL = 46  # local error tolerance (numerics.TOL x step_factor^5, floored)
DT = 47  # fixed step of the RK4 baseline [s]
H_MAX = 48  # largest step [s]
SNAP = 49  # slip [m/s] under which a load without contacts rides the belt in closed form
N_P = 50  # length of the header; the crank-rocker table follows it (drive.py)

# law / drive / profile codes
LAW_HERTZ, LAW_LINEAR = 0, 1
DRIVE_FLEXIBLE, DRIVE_RIGID, DRIVE_FREE = 0, 1, 2
PROFILE_CRANK_ROCKER, PROFILE_HARMONIC = 0, 1

G = 9.81  # m/s^2, MODEL.md §6


# --- one load of a stream (MODEL.md §14): the entries of p that change with the load, in the
# order of a row of the kernel's `loads` table (setup.load_table); the rest of p is the scene's ---
LOAD_SLOTS = (LL, AA, M1, DP, RS, PHI0, I1, KC, CD, KLIN, FMAX, MMAX, RHO, FFORCE)
N_LOAD = len(LOAD_SLOTS)
