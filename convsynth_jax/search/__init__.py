"""Audio-constrained search: constraints, the paper's stochastic greedy DFS, a JAX beam search, a checker."""
