"""Policy transfer from fixed-step to event-driven simulation (C8, C9), and the studies that explain
it: the dT grid (X3), the same-instant order (X4), the learner ablation (X5), C9's inputs, and the
heuristics on the same test episodes. Their shared pieces: ``study``."""
