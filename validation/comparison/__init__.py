"""wearbench.validation.comparison: measurement against theory, window by window.

A theory curve for a session (``theory``), lag search and DTW (``alignment``, ``dtw``), the window
scores (``metrics``), the classic pipeline against one theory (``compare``), and five-cycle windows
and bands against a theory ensemble (``windows``, ``bands``). Imports ``measurement`` and
``inference`` (the ensembles and the state statistics a window verdict uses).
"""
