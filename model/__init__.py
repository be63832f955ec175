"""wearbench.model"""
