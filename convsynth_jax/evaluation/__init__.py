"""Experiments support: leave-one-out folds and windows, objective metrics, collection of sweeps."""
