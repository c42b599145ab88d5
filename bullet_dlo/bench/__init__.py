"""Benchmarks: scenarios with known answers, work-precision sweeps, stability maps, peers."""
