"""Statistics: co-occurrence tables (``stats.cooccurrence``), contingency/permutation/proportion tests
(``stats.hypothesis``); distribution fits live in ``stats.fits`` (imported on demand, not here).

The tests' names load on first use (PEP 562), so that importing ``convsynth_jax.stats.params`` (as the
configuration does) does not import SciPy's statistics."""
import importlib

_EXPORTS = ("ContingencyResult", "CountError", "ProportionTest", "chi2_independence", "permutation_test", "prop_test",
            "proportion_test")
__all__ = list(_EXPORTS)


def __getattr__(name):
    if name in _EXPORTS:
        return getattr(importlib.import_module(".hypothesis", __name__), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
