"""Benchmarks of accuracy against cost: the integrators (method, work_precision, stability, kinks)
and the fidelity levels (fidelity)."""
