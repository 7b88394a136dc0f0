"""The errors a user can meet, in one leaf module (it imports nothing of the package, so every
layer raises them without importing another).

Bad input gets one clear message naming the value and what is allowed; the CLI prints it and
exits with code 2.
"""
from __future__ import annotations


class ParameterError(ValueError):
    """Bad user input: names the parameter, the value and what is allowed."""


class UsageError(ValueError):
    """A command-line or API mistake that is not about a parameter value (exit code 2)."""
