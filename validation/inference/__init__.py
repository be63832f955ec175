"""wearbench.validation.inference: which state, how much clearance and wear, over a bench's life.

Theory ensembles (``ensemble``), the statistics of a state's cycle features (``statistics``), the
sensor path as nuisance parameters (``sensor_path``), identification among candidate states
(``identify``), the sensor-path calibration and the states relative to it (``calibration``,
``relative_states``), the clearance-and-wear estimator (``estimate``), tracking over a life
(``track``) and the benches' move from new to worn (``move``). Imports ``measurement``.
"""
