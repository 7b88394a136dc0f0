"""The physics of MODEL.md: parameters, laws, drive, calibration, the compiled scenes, simulate."""
