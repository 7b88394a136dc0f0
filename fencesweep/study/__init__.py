"""Studies over many scenes, in wings that import only the wings listed before them:

  store/     the Parquet tables a study writes and reads (store/table.py), one writer per output
             (store/lock.py)
  spec/      a sweep spec from YAML (spec/file.py): its axes, scenes and cases (spec/spec.py,
             spec/axes.py) and its envelope:, design: and sensitivity: sections
  sweep/     a spec's scenes run as one table (sweep/pipeline.py): plan, chunks, compute,
             assemble, verify, estimate
  design/    an envelope's design points judged over their loads (design/judge.py), their table
             (design/points.py), the design search and the sensitivity study
  adaptive/  `fencesweep grid --adaptive`: a design map's verdicts from a fraction of its cycles
  risk/      `fencesweep risk`: per element, the share of a parcel mix that breaks a constraint,
             sampled round by round until it is known to lie below or above p_max
  api.py     the Python API of the studies (fencesweep.grid, estimate, design, sensitivity, risk, points)
"""
