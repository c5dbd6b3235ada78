"""Simulated VDA 5050 robots for tests, demos and benchmarks (see README.md)."""
