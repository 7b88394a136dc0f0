"""The physics of docs/model.md: parameters, laws, drive, calibration, the compiled scenes, simulate."""
