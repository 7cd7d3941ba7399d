"""Test oracles: slow, obvious reference versions of the fast kernels (graph construction, beam search
and its look-ahead, the CDBN's HMM recursions). Tests and benchmarks compare the kernels with them;
no library module imports this package (an import-linter contract in pyproject.toml checks it)."""
