"""Environments: one package per simulated process (``repro.envs.<name>``)."""
