"""wearbench.synthetic: sessions and lives of known truth, made on the emulated bench.

A truth is a candidate state played by the bench emulator on a bench drawn from the bench file's
``[tolerances]`` (``truths``); a life is such a bench worn over several sessions (``lives``). What
the demo records, what ``wearbench estimator --lives`` measures the move on, and what the
benchmarks judge the methods with. Imports the emulators, acquisition and validation.
"""
