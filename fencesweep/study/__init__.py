"""Studies over many scenes: sweep specs, sweeps, the Parquet store, envelopes, design, sensitivity."""
