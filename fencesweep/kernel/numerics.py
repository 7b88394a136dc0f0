"""Every step size and tolerance of the engine, in one place, each with its reason.

The physics has no tunable constants: these settle only how finely the equations of
docs/model.md are solved. model/prepare.py puts them into the kernel's parameter vector
(model/layout.py); the kernels read them from there. `benchmarks/work_precision.py` measures what they buy.
"""
from __future__ import annotations

#: Integrators (params `integrator`): the default embedded pair with error control, and the
#: fixed-step classical RK4 of the first engine, kept as the baseline row of the benchmarks.
#: Not a higher-order pair: DOP853 took fewer steps but more right-hand sides a cycle, and
#: needed a tighter tolerance to keep the validation set within 1e-4, so it was slower.
INTEGRATORS = ("dopri5", "rk4")

#: Local error tolerance at step_factor = 1. Every step keeps the difference of the 5th- and
#: 4th-order solutions below TOL relative to the state (rtol) and to the scene's scales (atol,
#: model/scenes/cycle/books.py error_scales: each component's allowed error moves a point of the scene by
#: TOL x the fence length, or TOL x the fastest drive-or-belt speed for velocities). Chosen
#: as the loosest power of ten at which the validation set (tests/test_validation.py) stays
#: within 1e-4 of the reference in peak_force, deflection_max and t_exit
#: (results/tolerance_scan.md).
TOL = 1e-6

#: Tolerance of the one-pulse scenes (`impact`, `freefall`, and the free-fall force that every
#: overload is divided by) at step_factor = 1: a pulse costs ~50 steps even this tight, so
#: their results are exact to ~1e-9 for the price of microseconds.
IMPACT_TOL = 1e-11

#: step_factor scales the tolerance as TOL * step_factor**TOL_EXPONENT: DOPRI5's local error
#: goes like h^5, so the steps scale about like step_factor (0.1: steps ~10x shorter), the
#: meaning step_factor had with fixed steps.
TOL_EXPONENT = 5.0

#: Tolerance floor: positions of order 1 m lose ~1e-16 relative per operation and a cycle
#: takes ~1e3 steps, so a local error below ~1e-13 cannot be met and would stall the step.
TOL_MIN = 1e-13

#: Step controller (Hairer, Norsett & Wanner I, II.4): safety factor on the predicted step and
#: the bounds on its growth per step, their recommended values.
SAFETY = 0.9
FAC_MIN = 0.2
FAC_MAX = 10.0

#: Largest step, as a fraction of the shortest time scale of the
#: fence (the cycle t_c, the element's natural period 2 pi sqrt(I2/K2)): a step then spans less
#: than a quarter of any oscillation of the fence, so each gap function of docs/model.md §5 has at
#: most one interior extremum in it, which the graze check and the peak finder (model/scenes/cycle/)
#: rely on (after the exit too: a free fence's deflection is not unimodal over a long step).
H_MAX_PER_PERIOD = 1.0 / 12.0

#: Events (contact changes, outcome events) are bisected on the dense output to this width
#: [s] (relative to max(1, t)): 40 halvings of a 1e-2 s step; far below the 1 ms floor of the
#: time results and the ~1e-6 s error of the dense output itself.
EVENT_TOL = 1e-12
#: At most this many evaluations of a slot's margin bracket a contact change before its
#: bisection (events.known_range): the Illinois method closes a smooth quantity's bracket to
#: 1e-12 in at most 15 (tests/test_search.py, a cubic); a bracket not closed by then leaves
#: the rest to the bisection.
MARGIN_EVALS = 16
#: ... and the bisection's first MARGIN_CHECKS midpoints outside that bracket, which it would take
#: as known, are tested (search.checked): a slot that changes and changes back inside the
#: step (a corner that enters while the manifold's axis turns to the face, and leaves when it turns
#: back) is then found as the bisection without the bracket finds it, wherever the excursion spans
#: one of them. MEASURED: results/kernel_cuts.md.
MARGIN_CHECKS = 3

#: A contact released inside a step (a PUSH slot that stops pushing) is located on the method's
#: own flow, not on the step's dense output alone: the step's later stages lie past the kink
#: of max(N, 0) (docs/model.md §4), which puts its dense output's velocities at the release
#: several atol off. events.release_state steps to the release, located anew on the dense
#: output of each step that passes it, until one passes it by at most RELEASE_TOL [s, relative
#: to max(1, t)], and takes the state there from that step's dense output: its error shrinks in
#: proportion to the overshoot, and 1e-6 s leaves a small fraction of atol. A try aims
#: RELEASE_MARGIN of the way from the located release to the last step that passed it, so that
#: it passes it again by ~10x less; RELEASE_TRIES bounds the tries (a release takes a few).
RELEASE_TOL = 1e-6
RELEASE_MARGIN = 0.1
RELEASE_TRIES = 4

#: First step after a contact onset, as a fraction of the undamped pulse time of the load at the
#: fastest closing speed (contact.pulse_time): the damped law's force grows like (t - t_A)^(1/4)
#: from the onset, which the error estimate of a long first step misjudges (a short tip clip
#: came out too strong), and a graze lasts far less than a pulse; from this start the
#: controller grows the steps by up to 10x a step, so the start costs ~4 steps per onset.
ONSET_STEP = 1e-6

#: The right-hand side takes the sine and cosine of the fence's and the load's angle from those of
#: the last angle it evaluated exactly (kernel/trig.py cos_sin_near), by the angle-addition
#: formula, while the angle is within TRIG_NEAR [rad] of it: within a step the stages' angles
#: differ by far less, and libm's sincos costs ~100 instructions where the formula costs ~20.
#: At 1/16 rad the series (to d^8 and d^9) are exact to 1e-18, and the result to an ulp or two
#: of libm's (each angle evaluated exactly again once it moved on by TRIG_NEAR, so errors
#: do not accumulate).
TRIG_NEAR = 1.0 / 16.0

#: Contact hysteresis, relative to the fence length (gaps) and to the free-fall force (forces):
#: a touching contact is released only when its gap exceeds it, and switches between pushing
#: and clipped only when its Kelvin force is beyond it. A load resting at zero depth or zero
#: force (long_near starts with a corner at the pivot, on the fence line) otherwise toggles
#: on rounding noise, ~1e-16 of the scales, at every step. 1e-10 l is ~1e-4 of the position
#: accuracy at the default tolerance: no result can see it. The same 1e-10 l grows the load in
#: the fence's touch test and is the bias that breaks ties in the choice of the fence's manifold
#: (docs/model.md (5.7)): a bias, not a memory, so that the choice is the state's alone.
CONTACT_HYSTERESIS = 1e-10

#: The face against the edge under the tip (docs/model.md (5.7)): the under-tip point U and the
#: tip end on U's edge are one point, measured along the fence's normal (U's own depth) and along
#: the edge's (the edge's own measure), apart by the factor cos of the edge's angle to the fence.
#: The face measures U along the edge's normal, the same number (a tie, which the bias gives to
#: the face while one of its corners touches), while that angle is within acos(1 - FACE_TOL)
#: (8 degrees): a face lying across the tip keeps its corner in the span and U (the paper's S3).
#: Beyond it U is measured along the fence's normal shrunk by 1 - FACE_TOL, continuously, and a
#: tilted edge under the tip takes over as before. With the 1e-10 l bias alone the choice flipped
#: where own (1 - cos) = 1e-10 l, at 6e-4 rad for a 0.6 mm overlap, and a face resting across the
#: tip chattered between two points and one (worst_tc row 1778: 685 steps, its peak 163-167 N with
#: the step; now 133.51 N at every step factor, 210 steps). Measured (the rows of results/audit.md,
#: the dP cuts of results/tip.md, the e = 1 graze): the same for FACE_TOL from 1e-3 to 5e-2; at 0.2
#: a tilted edge's corner and tip both pushed again (humps 2.1, the graze's energy off 1.9e-3); at
#: 1e-5 the rigid cut's hump rose from 1.33 to 1.76.
FACE_TOL = 0.01

#: A touch (docs/model.md (11.10)): the load-fence force above TOUCH_FORCE x the free-fall force
#: F_ff (~6 uN for the defaults); touches give n_impacts and contact_time (t_A dated from the
#: force's first onset, t_B where the last touch falls to the floor). Without a floor a load
#: resting on the fence at rounding-noise force (a contact at zero depth) "touched" until a step
#: happened to clip it, so its contact_time depended on the step. The validation's rail touches
#: use the same fraction. t_A is dated from the onset of the force episode in which the floor is
#: passed: dated from where the force passes the floor, a touch whose force grows slowly from 0
#: (a corner squeezed at the pivot) began where the steps happened to fall.
TOUCH_FORCE = 1e-9

#: A gap that opens at both ends of a step can still dip to contact inside it (a fence tip that
#: skims along an edge of the load within one long step). Its minimum is searched on the dense
#: output when the cubic through the gap's end values and rates dips below DIP_MARGIN of the
#: smaller end gap (events.dip_candidate): a margin, as the cubic only estimates the dip.
DIP_MARGIN = 0.5
#: ... and the step after a long one is cut to the time in which a gap apart at its end would
#: close at its end rate and its acceleration over the step (run.approach_step), for a dip that
#: the cubic does not see (a gap opening fast at the step's end). Not below APPROACH_FLOOR x the
#: largest step, so that a gap that stays at ~0 after a release does not make the steps vanish.
APPROACH_FLOOR = 0.01

#: Peaks of the tracked quantities (forces, deflection, alpha) are refined by Brent's search
#: (search.peak_max) on the dense output of the two steps around a local maximum of the samples, to
#: this width in units of the window (value error ~ (width)^2: far below 1e-6 relative), and
#: only for local maxima within PEAK_CANDIDATE of the running maximum.
PEAK_TOL = 1e-6
PEAK_CANDIDATE = 0.999
#: A force's interior maximum can lie far above both ends of a step: two corners striking at
#: once (a face landing flush on the fence) make a short pulse whose top can fall between two
#: samples. So a step is judged when the force may reach PEAK_CANDIDATE of the running maximum inside
#: it (peaks.reach): the larger end value plus PEAK_REACH times the larger of the step's rise
#: and the rise at the previous step's rate (a concave top stays under the tangent at the
#: start, whose slope the previous secant exceeds; 2 covers a rise still convex there). After
#: an event the rate before it is no guide (a corner lets go and the other's force rises), and
#: the first step is judged whatever its ends.
PEAK_REACH = 2.0

#: Slip speed [m/s, relative to eps_v] under which a load without contacts is put back on the
#: belt's closed-form ride (docs/model.md §8). Below eps_v the belt friction decays the slip at the
#: rate lambda = mu1 g / eps_v (~4e3 1/s by default), so the ride that remains costs a position
#: error of at most slip / lambda = 1e-3 eps_v^2 / (mu1 g) (~2.5e-10 m), and the explicit
#: method no longer has to step that stiff decay.
SNAP_SLIP = 1e-3

#: Fixed step of the RK4 baseline [s] at step_factor = 1 (params `dt` overrides it): 1/50 of the
#: default pulse (~5e-4 s for small loads), i.e. about the first engine's finest step.
DT_RK4 = 1e-5

#: Step budget of one cycle: far above the ~1e3 steps of an ordinary cycle; a run that needs
#: more ends with status "failed: step budget exhausted".
MAX_STEPS = 5_000_000

#: A step below this [s, relative to max(1, t)] cannot advance t in double precision: the run
#: ends with status "failed: step size underflow".
H_MIN = 1e-14

#: The step's tolerance is scaled (atol and rtol together; cycle/run.py set_tolerance):
#:   * by APPROACH_TOL while the load is on the belt and touches nothing: the positions at which
#:     a contact begins decide how deep it goes, and a graze (a touch of ~1e-5 m) is only as deep
#:     as the fence and the load are accurate; its force (~D^1.5, D^0.25 D', docs/model.md §4) is
#:     ill-conditioned in the penetration D. The approach is a small share of a cycle's steps.
#:     The same holds while the load lets go of the fence slowly: its deepest fence contact
#:     less than LIGHT_DEPTH position tolerances (TOL l) deep and opening. There the force is a
#:     small difference of its elastic and damping parts, and a position error of TOL l moves
#:     its return to zero by milliseconds. Not while the contact closes: tightening the onsets
#:     too (light contacts of any rate) moved other results further from the reference.
#:     The depth alone misses a release whose damping part cancels a deeper contact's elastic
#:     part (a heavily damped fence letting a load go slowly); so a contact letting go counts as
#:     light too while the fence's force is below LIGHT_FORCE x F_ff (~6 N for the defaults): a
#:     release after an impact passes through it in a step or two. And for the step in which a
#:     contact force (the fence's or the rail's), falling at the last step's rate, would reach
#:     LIGHT_FORCE x F_ff (run.release_ahead): where a damped contact lets go, its elastic and
#:     damping parts cancel, as ill-conditioned in the state as an onset. A 1.35 ms step from 73 N
#:     to the release put it 5.6e-6 s early and 4.9e-4 rad/s into the load's spin, and its next
#:     impact, 55 ms later, 1.6e-3 low (sweeps/fig5a_worst_v.yaml, rigid, R_s -0.7; the audit's
#:     last peak_force rows over 1e-3 were all of this kind, one a rail's release).
#:   * by FREE_TOL throughout for a free fence (drive = free): nothing pulls it back to its
#:     drive, so an error in its rate integrates into its angle until t_c (a coast after the
#:     load left), and an impact on it passes the load's errors into that rate.
APPROACH_TOL = 1.0 / 30.0
LIGHT_DEPTH = 100.0
LIGHT_FORCE = 1e-3
FREE_TOL = 1.0 / 16.0
