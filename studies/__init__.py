"""wearbench.studies: the paper's studies, parameter sweeps and their figures, built on the model.

``study`` runs the wear and clearance studies of a bench, ``sweep`` a grid of design points, each as
tasks of :mod:`wearbench.compute`; ``plots``, ``study_plots`` and ``wear_report`` draw and write their
results. Stands above ``model`` and ``compute``; nothing below imports it.
"""
