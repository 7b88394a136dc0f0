"""`python -m fencesweep`: the same command line as the `fencesweep` script."""
import sys

from .cli import main

sys.exit(main())
