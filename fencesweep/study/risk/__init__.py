"""`fencesweep risk SPEC`: the probabilities that a parcel of a mix is hit too hard, not sorted, deflects
the fence too far or leaves it ringing, per element and operating point, with honest intervals.
sequential.py decides the units round by round (pure: any engine, or a Bernoulli stand-in),
run.py runs the rounds' cycles through the sweeps' machinery, table.py writes the tables."""
