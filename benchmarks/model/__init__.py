"""Benchmarks of the model: speed against error, where a revolution's time goes, bit identity and
statistical equivalence of a changed model, wear convergence, a peer's timing."""
