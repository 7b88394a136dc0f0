"""Errors of the command line and the sweep layer that are not about a parameter value.

Bad parameter values raise params.ParameterError (a bad spec: spec.SpecError); this module
holds the rest, so that the sweep layer can raise them without importing the CLI.
"""
from __future__ import annotations


class UsageError(ValueError):
    """A command-line mistake that is not about a parameter value (exit code 2)."""
