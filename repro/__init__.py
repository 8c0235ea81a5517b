"""Reproduction suite for Menda et al., "Deep Reinforcement Learning for Event-Driven Multi-Agent
Decision Processes": environments, the PS-TRPO/M-GAE learner, and one driver per figure and
table."""

__version__ = "0.1.0"

from repro.core.numba_cache import install as _install_numba_cache_lock

_install_numba_cache_lock()  # before any kernel compiles, in every process (workers import repro)
