"""wearbench.acquisition"""
