"""torch's intra-op threads for madsim's small networks.

The policies and value functions here are MLPs of a few dozen units, evaluated one
observation at a time. torch splits even those over its intra-op thread pool (one thread per
core by default), and on a busy 2-core machine the threads' hand-offs cost far more than the
arithmetic: measured on this project's machine (load 4), 20 evaluation episodes of Experiment
6's two RLlib policies took 17.0 s with torch's default 2 threads and 0.26 s with 1, with the
same actions. A thread count also changes the bits of a training update (its reductions are
split differently), so training pins it: the same seed gives the same policy on a 2-core
laptop and a 64-core server.
"""

from __future__ import annotations

from contextlib import contextmanager

TRAINING_THREADS = 1
"""torch's intra-op threads while madsim trains (SB3 and RLlib drivers) or evaluates a policy."""


@contextmanager
def torch_threads(n: int = TRAINING_THREADS):
    """Run the block with torch's intra-op threads set to `n`, restoring the caller's count
    after it (about 0.2 us a call: cheap enough to wrap every policy evaluation)."""
    import torch

    if isinstance(n, bool) or not isinstance(n, int) or n < 1:
        raise ValueError(f"torch threads must be an int >= 1, got {n!r}")
    before = torch.get_num_threads()
    if before == n:
        yield
        return
    torch.set_num_threads(n)
    try:
        yield
    finally:
        torch.set_num_threads(before)
