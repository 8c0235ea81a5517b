"""Process-wide settings for training: made once per process, by its entry point.

- torch computes on one thread. The policy's and baseline's products are small (an epoch's batch
  times 32 or 64 units), and on a machine shared with other work a thread that waits for a busy
  core slows every product; one thread also makes a run's bits independent of the machine's core
  count.
- glibc's malloc keeps freed memory for reuse (:func:`repro.runs.memory.keep_freed_memory` says
  why).

The commands that train in their own process (``train``, ``bench-learn``) make these settings
before they start, and a sweep's worker processes before each run. A library user who builds a
:class:`~repro.learn.trainer.Trainer` directly calls :func:`configure_process` once first, to get
the runs the command line gets.
"""

from __future__ import annotations

from repro.runs.memory import keep_freed_memory


def configure_process() -> None:
    """Make the process-wide settings training runs with (the module docstring says which and
    why). Idempotent."""
    import torch

    torch.set_num_threads(1)
    keep_freed_memory()
