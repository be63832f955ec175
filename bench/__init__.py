"""The bench: its schema, its units, and reading bench files. The lowest layer of wearbench.

Everything else stands on it (model, hardware, acquisition, validation, cli); it imports nothing
from wearbench outside this package.
"""
