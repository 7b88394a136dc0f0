"""The integrator contract and Numba's set-up: no physics here."""
