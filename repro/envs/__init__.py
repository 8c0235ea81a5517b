"""Event-driven multi-agent environments; each subpackage provides ``make_env`` (its fast engine)
and ``make_reference_env`` (its SimPy reference), both implementing
:class:`repro.core.rollout.BatchEnv`."""
