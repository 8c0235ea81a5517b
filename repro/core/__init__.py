"""Infrastructure shared by every driver: errors, scales, atomic writes, provenance, statistics."""
