"""Reproduction suite for Menda et al., "Deep Reinforcement Learning for Event-Driven Multi-Agent
Decision Processes": environments, the PS-TRPO/M-GAE learner, and one driver per figure and
table."""

__version__ = "0.1.0"
