"""Run bookkeeping, shared by training and the studies: atomic files, result and figure pairs with
their provenance, folder locks, run folders, the pinned kernels, memory, workers, progress, the
numba cache lock and statistics. It imports from ``repro.core`` only; the environments never import
it, so an environment can be used without it."""
