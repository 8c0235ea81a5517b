"""Races (C10, C11, X2): the race-condition table, races in the wildfire simulator, and the compute
of event-driven against time-stepped simulation. Shared mathematics: ``study``."""
