"""`python -m fencesweep`: the same command line as the `fencesweep` script."""
import sys

from fencesweep.cli import main

sys.exit(main())
