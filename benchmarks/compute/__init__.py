"""Benchmarks of the compute layer: scale-out of a batch, the cost of a study."""
