"""convsynth_jax: statistics-based motion synthesis for dyadic conversations, in JAX."""
__version__ = "0.1.0"
