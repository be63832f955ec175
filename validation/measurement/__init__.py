"""wearbench.validation.measurement: a recorded session as validation sees it, and its features.

The session's samples cut into crank cycles (``session``, ``cycles``), the zero-phase filters
(``filters``), the per-cycle features addressed by crank angle (``features``), the accelerometer
chain's stated delay (``chain_delay``) and the tap test that measures it (``tap_test``). The floor
of validation: imports the bench and acquisition layers, no other part of validation.
"""
