"""The warm kernel: CPU time of one cycle through the public call `fencesweep.simulate`, after a
`setup` that ran the same cycles once (the Numba cache loaded, or compiled in a new environment)."""
import itertools
import time

import fencesweep

from . import CASES, DRIVES, main_job_sample


class NamedCases:
    """One cycle of a named case (docs/model.md §12, B2 = 72, K2 = 570) on each drive."""
    params = (list(CASES), list(DRIVES))
    param_names = ["case", "drive"]
    timer = time.process_time
    timeout = 600  # the first setup in a new environment compiles the kernel

    def setup(self, case, drive):
        fencesweep.simulate("cycle", case=case, drive=drive)

    def time_cycle(self, case, drive):
        fencesweep.simulate("cycle", case=case, drive=drive)


class MainJobSample:
    """The main job's fixed sample of 60 scenes: each call runs the next scene of the sample, and a
    sample of 60 calls runs each scene once, so the time is a cycle's mean over the sample."""
    number = 60
    warmup_time = 0
    timer = time.process_time
    timeout = 600

    def setup(self):
        self.sample = main_job_sample()
        self.steps = [fencesweep.simulate("cycle", case=c, B2=b, K2=k)["n_steps"] for c, b, k in self.sample]
        self.scenes = itertools.cycle(self.sample)

    def time_cycle(self):
        c, b, k = next(self.scenes)
        fencesweep.simulate("cycle", case=c, B2=b, K2=k)

    def track_steps(self):
        """The integrator's accepted steps a cycle, the sample's mean (deterministic)."""
        return sum(self.steps) / len(self.steps)

    track_steps.unit = "steps"
