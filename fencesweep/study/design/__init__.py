"""Design over a load envelope: judge.py judges each design point over its loads, points.py writes
the per-design-point table, search.py finds the element that keeps every constraint
(`fencesweep design`), sensitivity.py gives the Sobol indices (`fencesweep sensitivity`)."""
