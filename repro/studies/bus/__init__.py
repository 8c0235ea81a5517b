"""The bus study (C1-C5): thresholds, training curves over lambda and the batch size, arrivals and
loads, and the evaluation of a bus policy. Shared pieces: ``policies`` and ``sweeps``."""
