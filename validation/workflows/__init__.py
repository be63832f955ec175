"""wearbench.validation.workflows: recorded sessions in, answers out.

The workflows behind ``identify``, ``estimate``, ``calibrate`` and ``track``: load the sessions,
group them by bench and commanded speed, build or load the theory they need on the compute layer,
and call ``inference`` and ``comparison``. The top of validation.
"""
