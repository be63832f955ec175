"""wearbench.hardware"""
