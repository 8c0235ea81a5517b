"""One driver per figure or table of the paper; each writes CSVs, provenance sidecars and plots."""
