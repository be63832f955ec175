"""wearbench.validation.estimation: how much clearance and wear, and how it moves over a bench's life.

The clearance-and-wear estimator over a design of clearances and cycles run (``estimate``), the
benches' move from new to worn measured on lives of known truth (``move``), and tracking one bench
over its sessions (``track``). Imports ``inference`` (ensembles, statistics, identification's fits)
and ``measurement``.
"""
