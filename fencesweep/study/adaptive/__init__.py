"""`fencesweep grid SPEC --adaptive` (run.py): refine.py decides which elements of a design map to
simulate and infers the others, maps.py lays out the maps of a spec, loads.py orders an element's
loads, evaluate.py simulates and judges a level's elements, points.py writes the points table."""
