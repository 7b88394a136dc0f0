"""A sweep spec (sweeps/README.md), checked: file.py reads the YAML; spec.py holds the scenes (axes.py
their values); envelope.py, design.py and sensitivity.py check the sections of those names."""
