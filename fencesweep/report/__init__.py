"""Presentation: tables computed from results, the markdown report, figures."""
