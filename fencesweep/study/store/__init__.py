"""The Parquet tables of a study: written atomically with their units and provenance, read back
whole (table.py); one writer per output (lock.py)."""
