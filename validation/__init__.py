"""wearbench.validation"""
