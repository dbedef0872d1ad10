"""Helpers shared by the benchmark scripts: timing (CPU and wall time of the same calls), profiles, provenance."""
