"""A spec's scenes run as one table (pipeline.py): plan.py maps scenes to distinct model runs and
chunks, compute.py runs the chunks (runs.py in one process), chunks.py reads them back, assemble.py
writes the table, verify.py (sample.py, accuracy.py) checks it, estimate.py says what a run would do,
output.py says where it writes, progress.py shows how far it is."""
