"""Benchmarks of validation: identification, estimation and tracking, window verdicts, sensor delays."""
