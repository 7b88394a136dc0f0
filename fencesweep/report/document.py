"""REPORT.md: the element to build first, then each result of the paper against ours, the stages,
the escapes, the design maps, the streams and the design for every package, written from the tables
and trajectories that analysis.py reads. write_report assembles the file from the sections:
answer_text.py (the opening, right under the title), paper_text.py (1, 4), fig5a_text.py,
maps_text.py (2), stream_text.py (6), design_text.py (7), risk_text.py (8); the title, the header, the list of
figures (3) and the notes (5) are here. Orchestration and bookkeeping only (no physics, no matplotlib).
"""
from __future__ import annotations

import os
import platform
from pathlib import Path

from fencesweep.report.analysis import (FREEFALL_LEVELS_H, PAPER_B2, PAPER_K2, RESIDUAL_MAX_DEG, STREAM_FIGURE_CYCLES,
                                        STREAM_FIGURE_TC, TABLES, TRAJECTORIES, read_table, table_path)
from fencesweep.report.answer_text import answer_lines
from fencesweep.report.fig5a_text import fig5a_section
from fencesweep.report.inputs import ReportInputs, report_inputs
from fencesweep.report.maps_text import maps_section, paper_element_section
from fencesweep.report.paper_text import differences_section, paper_section, stage_section
from fencesweep.report.stream_text import stream_section


# ---------------------------------------------------------------------------- the report
def _provenance(res: Path) -> str:
    from fencesweep.study.store import table as store

    for name in TABLES:
        p = table_path(res, name)
        if p.exists():
            v = store.read_metadata(p).get("versions", {}) or {}
            return (f"fencesweep {v.get('fencesweep', '?')} (sources sha256 {str(v.get('source_hash', '?'))[:12]}), "
                    f"numba {v.get('numba', '?')}, numpy {v.get('numpy', '?')}, python {v.get('python', '?')}")
    return "unknown"


def write_report(res: Path = Path("results"), residual_max_deg: float = RESIDUAL_MAX_DEG,
                 out: Path | None = None) -> Path:
    """Write <res>/REPORT.md from the tables and trajectories in <res> (figures linked from figures/).

    One function per section, each returning its lines; every number in them is read off the inputs."""
    res = Path(res)
    out = Path(out) if out else res / "REPORT.md"
    I = report_inputs(res, residual_max_deg)
    sections = (
        _title,
        _answer,                # the element to build, its margins, what it was checked on (answer_text.py)
        _header,                # how the file is made, the engine, the working point
        paper_section,          # 1. the paper's results side by side (paper_text.py)
        stage_section,          #    stage sequences
        fig5a_section,          #    Fig. 5a: the worst-case arrangement, the jumps, the escapes (fig5a_text.py)
        maps_section,           # 2. design maps and the two-case pick (maps_text.py)
        paper_element_section,  #    the paper's 72/570 against the constraints, the threshold, the reading
        _figures_section,       # 3. figures
        differences_section,    # 4. where we differ from the paper (paper_text.py)
        _notes_section,         # 5. notes
        _stream_part,           # 6. consecutive cycles (stream_text.py)
        _design_part,           # 7. design for every package (design_text.py; empty until `fencesweep design`)
        _risk_part,             # 8. risk from a parcel mix (risk_text.py; empty until `fencesweep risk`)
    )
    L: list[str] = []
    for section in sections:
        L += section(I)
    out.write_text("\n".join(L) + "\n")
    return out


def _title(I: ReportInputs) -> list[str]:
    return ["# Results: the seed paper side by side, and the B2 x K2 design maps", ""]


def _answer(I: ReportInputs) -> list[str]:
    """The element to build over the load envelope (empty until `fencesweep design` has run); the
    picks of the two named loads' maps are named in its comparison."""
    return answer_lines(I.res, I.D)


def _header(I: ReportInputs) -> list[str]:
    p = I.base
    law = 'modified Kelvin ("hertz")' if p["contact_law"] == "hertz" else p["contact_law"]
    L = ["Everything in `results/` (sweep tables, trajectories, figures, this file) is regenerated from "
         "scratch by one command, run from the repository root:", "", "    bash results/regenerate.sh", ""]
    start = os.environ.get("FENCESWEEP_REGEN_START")
    if start:
        import time

        L.append(f"(This file was written {time.time() - float(start):.0f} s after that command started, on "
                 f"{os.cpu_count()} cores, {platform.system()}.)")
    L += [f"Engine: {_provenance(I.res)}. Paper: Piatkowski & Sempruch, *Active fence with flexible element in a "
          "drive system* (`shared/seed/active-fence-paper.txt`); the physics is docs/model.md. Unless a row "
          f"says otherwise: t_c = {p['t_c']:g} s, v = {p['v']:g} m/s, R_s = {p['R_s']:g}, m1 = {p['m1']:g} kg, "
          f"m2 = {p['m2']:g} kg, e = {p['e']:g}, {law} law, flexible element B2 = {p['B2']:g} N m s/rad, K2 = {p['K2']:g} N m/rad.", ""]
    return L


# ------------------------------------------------------------------ 3. and 5.
def _figures_section(I: ReportInputs) -> list[str]:

    es = sorted({o.get("e", I.base["e"]) for c, o in TRAJECTORIES.values() if o.get("drive") == "rigid"})
    el = f"{PAPER_B2:g}/{PAPER_K2:g}"
    figs = [
        ("fig2_linear_law.png", "paper Fig. 2: force of the first impact of small_far, linear Kelvin law; (a) rigid "
         f"fence, e = {' / '.join(f'{e:g}' for e in es)}, (b) e = {I.base['e']:g}, rigid / flexible {el} / free fence"),
        ("fig3_modified_law.png", "paper Fig. 3: the same with the modified Kelvin law (eq. 3)"),
        ("fig4_fence_moment.png", "paper Fig. 4: (a) the drive's kinematic input alpha_w, (b, c) moment of the "
         "load on the fence for both named cases, stages shaded, A / B / C marked"),
        ("fig5a_overload_v_tc.png", f"paper Fig. 5a: overload against v (t_c = {I.base['t_c']:g} s) and t_c "
         f"(v = {I.base['v']:g} m/s), rigid / flexible / free fence, with free-fall levels from H = "
         f"{' / '.join(f'{h:g}' for h in FREEFALL_LEVELS_H)} m; the named cases, and the worst over the load's "
         "placements (the paper's §4.1 arrangement)"),
        ("fig5b_quotient_m2.png", "paper Fig. 5b: peak force rigid / free (and rigid / flexible) against m2"),
        ("fig6_psi1_b2.png", "paper Fig. 6: damper energy and maximal deflection against B2 at Psi = 1"),
        ("fig7_fence_response.png", "paper Fig. 7: alpha and alpha_w against time, A, B, C marked, and the "
         "deflection alpha - alpha_w"),
        ("fig8_load_path.png", "paper Fig. 8: path of the load's centroid, rigid vs flexible fence, both cases"),
        ("map_small_far.png", "design maps, small_far: overload, deflection_max, residual amplitude, outcome"),
        ("map_long_near.png", "design maps, long_near"),
        ("map_both.png", "both cases: worst overload over the feasible region, the first constraint that fails, "
         "the two-case pick"),
        ("cycle_small_far.png", "one cycle in frames: load, fence, drive lever, belt, contact forces (small_far, "
         f"flexible {el})"),
        ("cycle_long_near.png", "the same for long_near"),
        ("recommended.png", "deflection and fence force over a cycle, both named cases: " + _recommended_figure(I)),
        ("stream_deflection.png", f"deflection over {STREAM_FIGURE_CYCLES} cycles back to back (scene stream) at "
         f"T = t_c, t_c = {' and '.join(f'{t:g}' for t in STREAM_FIGURE_TC)} s: the paper's {el}, the two-case pick and "
         "the well-damped element (section 6)"),
    ]
    return ["## 3. Figures (`results/figures/`)", ""] + [f"* [`{f}`](figures/{f}): {t}" for f, t in figs] + [""]


def _recommended_figure(I: ReportInputs) -> str:
    """What recommended.png draws: the element to build (when the design has run), then the others."""
    from fencesweep.report.analysis import envelope_element

    el = f"the paper's {PAPER_B2:g}/{PAPER_K2:g}, the two-case pick and the well-damped pick"
    env = envelope_element(I.res)
    return (f"the element to build, {env['B2']:g}/{env['K2']:g} (`design/recommended.json`), against {el}" if env
            else el)


def _notes_section(I: ReportInputs) -> list[str]:
    return ["## 5. Notes", "",
            "* The free fence of Fig. 5a is released at the first contact (docs/model.md §3); it is an "
            "idealisation for "
            "the impact, and the loads it touches are not all scraped (marked x in Fig. 5a).",
            "* `residual_deflection` is |alpha - alpha_w| at t_c, one snapshot: for a lightly damped element it can "
            "be small by the phase of a swing that has not died out. The maps therefore judge \"home\" by "
            "`residual_amplitude` (deflection and rate at t_c combined, docs/model.md §11); section 6 answers the "
            "question the criterion stands for directly, by running the cycles back to back.", ""]


# ------------------------------------------------------------------ 6. and 7.
def _stream_part(I: ReportInputs) -> list[str]:
    return stream_section(read_table(I.res, "period")) if table_path(I.res, "period").exists() else []


def _design_part(I: ReportInputs) -> list[str]:
    from fencesweep.report.design_text import design_section  # empty until `fencesweep design` has run

    return design_section(I.res)


def _risk_part(I: ReportInputs) -> list[str]:
    from fencesweep.report.risk_text import risk_section  # empty until `fencesweep risk sweeps/risk.yaml` has run

    return risk_section(I.res)
