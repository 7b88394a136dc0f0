"""What REPORT.md is written from: the sweep tables, the trajectories of TRAJECTORIES and the
B2 x K2 design maps, read once (report_inputs) and handed to every section of the report.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from fencesweep.report.analysis import (Design, RESIDUAL_MAX_DEG, TRAJECTORIES, WORST_TABLES, design, read_table,
                                        read_traj, table_path)


@dataclass
class ReportInputs:
    """What REPORT.md is written from: the sweep tables, the trajectories of TRAJECTORIES (T, their
    results R), the design maps D; `worst` holds the worst-case tables of Fig. 5a that exist."""

    res: Path
    residual_max_deg: float
    T: dict
    R: dict
    b2k2: object
    psi: object
    f5a: object
    f5b: object
    ffh: object
    D: Design
    worst: dict

    @property
    def base(self) -> dict:
        """The parameters of the paper's working point (the flexible small_far run)."""
        return self.T["small_far_flexible"].attrs["params"]


def report_inputs(res: Path, residual_max_deg: float = RESIDUAL_MAX_DEG) -> ReportInputs:
    res = Path(res)
    T = {n: read_traj(res, n) for n in TRAJECTORIES}
    b2k2 = read_table(res, "b2k2")
    worst = {n: read_table(res, n) for n in WORST_TABLES if table_path(res, n).exists()}
    return ReportInputs(res, residual_max_deg, T, {n: df.attrs.get("results") or {} for n, df in T.items()},
                        b2k2, read_table(res, "psi_b2"), read_table(res, "fig5a"), read_table(res, "fig5b"),
                        read_table(res, "freefall_H"), design(b2k2, residual_max_deg), worst)
