"""Reproduction suite for Menda et al., "Deep Reinforcement Learning for Event-Driven Multi-Agent
Decision Processes": environments, the PS-TRPO/M-GAE learner, and one driver per figure and
table."""

__version__ = "0.1.0"

from repro.runs.kernels import pin as _pin_kernels

_pin_kernels()  # before numpy is imported and torch computes (repro.runs.kernels says why)

from repro.runs.numba_cache import install as _install_numba_cache_lock  # noqa: E402

_install_numba_cache_lock()  # before any kernel compiles, in every process (workers import repro)
