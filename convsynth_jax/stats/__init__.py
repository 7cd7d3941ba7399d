"""Statistics: co-occurrence tables, contingency/permutation/proportion tests, distribution fits."""
from .tests import chi2_independence, permutation_test, prop_test, proportion_test  # noqa: F401
