"""Figures: the paper's Figs 2-8 recomputed, B2 x K2 design maps, one cycle in frames, a stream.

`fencesweep plot [NAME ...]` draws PNGs into <results>/figures/ from the sweep tables and
trajectories in <results>/ (fencesweep.report.analysis lists which: TABLES, TRAJECTORIES). Drawing
only: no physics here; every number comes from a Parquet file the engine wrote. This module is the
registry (FIGURES) and `plot`; the figures are drawn in figures_paper_cycles.py (Figs 2-4, 7, 8),
figures_paper_sweeps.py (Figs 5a, 5b, 6), figures_maps.py (design maps, the element to build)
and figures_cycle.py (cycle frames, the stream), with what they share in figures_common.py.

    fencesweep plot trajectories     # run the single cycles the figures need (engine)
    fencesweep plot all              # every figure
    fencesweep plot fig5a maps       # some of them
    fencesweep plot report           # results/REPORT.md

matplotlib is the optional extra `[plot]`; it is imported inside the functions (Agg
backend), so this module imports without it.
"""
from __future__ import annotations

from pathlib import Path

from fencesweep.report import analysis as RP
from fencesweep.report.figures_cycle import cycle, stream
from fencesweep.report.figures_maps import maps, recommended
from fencesweep.report.figures_paper_cycles import fig2, fig3, fig4, fig7, fig8
from fencesweep.report.figures_paper_sweeps import fig5a, fig5b, fig6


# ---------------------------------------------------------------------------- registry and CLI
FIGURES = {
    "fig2": (fig2, "paper Fig. 2: impact force, linear Kelvin law"),
    "fig3": (fig3, "paper Fig. 3: impact force, modified Kelvin law"),
    "fig4": (fig4, "paper Fig. 4: drive input and moment of the load on the fence"),
    "fig5a": (fig5a, "paper Fig. 5a: overload against v and t_c"),
    "fig5b": (fig5b, "paper Fig. 5b: quotient of peak forces against m2"),
    "fig6": (fig6, "paper Fig. 6: damper energy and maximal deflection at Psi = 1"),
    "fig7": (fig7, "paper Fig. 7: alpha, alpha_w with A, B, C"),
    "fig8": (fig8, "paper Fig. 8: load path, rigid vs flexible"),
    "maps": (maps, "design maps over B2 x K2 (per case and both)"),
    "cycle": (cycle, "one cycle in frames, per case"),
    "recommended": (recommended, "the element to build (recommended.json) against the paper's 72/570 and the maps' picks"),
    "stream": (stream, "deflection over 10 cycles back to back (scene stream), three elements"),
}
#: number of PNG files `plot all` writes
N_FILES = 8 + 3 + 2 + 1 + 1


def plot(names, res: Path = Path("results"), out: Path | None = None,
         residual_max_deg: float = RP.RESIDUAL_MAX_DEG) -> list:
    """Draw the named figures ('all' for every one); return the PNG paths written."""
    res = Path(res)
    out = Path(out) if out else res / "figures"
    names = list(FIGURES) if (not names or "all" in names) else list(names)
    paths = []
    for n in names:
        fn = FIGURES[n][0]
        got = fn(res, out, residual_max_deg) if n == "maps" else fn(res, out)
        paths += got if isinstance(got, list) else [got]
    return paths
