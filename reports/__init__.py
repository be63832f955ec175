"""wearbench.reports: what a lab hands on: figures, tables and the self-contained ``report.html``.

Above validation: it draws and writes the results validation computes (comparisons, identifications,
window verdicts, estimates, tracks); validation itself draws nothing.
"""
