"""Scene `cycle`: one sorting work cycle (docs/model.md §1-§6, §9-§11), in the order a step meets it:

  layout.py   the state, the work arrays (`Work`) and the index constants of both;
  rhs.py      the right-hand side: the fence (§3), the load's contacts (§5) and belt (§6);
  slots.py    the contact slots' codes, gaps and sides at a state (§5), the stages (§10);
  events.py   events located inside a step on its dense output: contact changes, grazes,
              outcomes (§9), and releases located on the method's own flow;
  peaks.py    the tracked maxima located inside a step (§11: peak forces, deflection, alpha);
  books.py    book-keeping: the run's start, contact changes, the load's exit, results (§11);
  run.py      the cycle's loop: kernel/driver.py's `integrate`, with `accept` for each step.

The entry point that runs cycles (one, or a stream of them: §14) is model/scenes/stream.py.
"""
