"""Statistics: co-occurrence tables (``stats.cooccurrence``), contingency/permutation/proportion tests
(``stats.hypothesis``); distribution fits live in ``stats.fits`` (imported on demand, not here)."""
from .hypothesis import (ContingencyResult, CountError, ProportionTest, chi2_independence,  # noqa: F401
                         permutation_test, prop_test, proportion_test)
