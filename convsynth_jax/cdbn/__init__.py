"""Constrained DBN (Sadoughi & Busso): features, HMM inference and EM in JAX, state merging, synthesis."""
