"""The Parquet tables of a study: written atomically with their units and provenance, read back
whole by plain pandas too (table.py, its columns: columns.py), as an xarray Dataset over the
spec's axes (dataset.py); one writer per output (lock.py)."""
