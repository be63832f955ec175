"""wearbench.validation.inference: which state a session is in, against theory ensembles.

Theory ensembles (``ensemble``), the statistics of a state's cycle features (``statistics``), the
sensor path as nuisance parameters (``sensor_path``), identification among candidate states
(``identify``), the sensor-path calibration and the states relative to it (``calibration``,
``relative_states``), verdict wording (``verdicts``) and the shipped and cached artefacts
(``artefacts``). Imports ``measurement``; the estimator and tracking build on it (``estimation``).
"""
