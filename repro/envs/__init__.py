"""Event-driven multi-agent environments: each subpackage provides a fast engine and a SimPy reference."""
