"""The last few model runs of any fit problem, remembered by the values of their inputs. A
diagnosis asks for the same run from different problems -- every candidate of a screen builds its
own problem at the current fit and evaluates it there, a probe revisits a point -- and a run's
result depends on its inputs alone, so a remembered run is the same bits as running it again."""
from __future__ import annotations

import numpy as np

RUNS = 32  # runs remembered, over all problems
RUN_SAMPLES = 1 << 16  # runs over more samples are not remembered (memory; a long run is rarely repeated)


class RunMemo:
    """The last `size` runs: (key, input arrays) -> tuple of result arrays. The key holds what is
    compared by identity or exactly (the library object, the order, the parameter vector's
    bytes); the input arrays are compared by value. Results come back as copies (callers write
    into them)."""

    def __init__(self, size: int = RUNS):
        self.size = size
        self.entries: list = []

    def get(self, key: tuple, arrays: tuple, compute) -> tuple:
        for k, args, value in self.entries:
            if k == key and all(np.array_equal(a, b) for a, b in zip(args, arrays)):
                return tuple(v.copy() for v in value)
        value = compute()
        if max(np.size(a) for a in arrays) <= RUN_SAMPLES:
            self.entries.insert(0, (key, tuple(np.array(a) for a in arrays), tuple(v.copy() for v in value)))
            del self.entries[self.size:]
        return value


MODEL_RUNS = RunMemo()
# the library's Jacobian calls apart: the screen's speed-ripple orders differ only in the drive's
# tangents, chained after the call (sampled.pointwise_columns), so at zero amplitude they make the
# same call
JACOBIAN_RUNS = RunMemo()
# the interval columns' sub-sample runs apart, more of them: a polar search's finalists are scouted
# from the starts their quick looks ran at, 17 quick looks earlier
DESIGN_RUNS = RunMemo(size=24)
