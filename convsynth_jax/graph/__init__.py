"""Motion-graph construction: transition-cost kernels, key states, thresholds, SCC pruning.

The names below load on first use (PEP 562), so that importing ``convsynth_jax.graph.params`` (as
the configuration does) does not import the kernels and JAX with them."""
import importlib

_EXPORTS = {"build_graph": ".build", "build_graph_from_clips": ".build", "MotionDatabase": ".database",
            "build_database": ".database", "MotionGraph": ".types", "load_graph": ".types"}
__all__ = sorted(_EXPORTS)


def __getattr__(name):
    if name in _EXPORTS:
        return getattr(importlib.import_module(_EXPORTS[name], __name__), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
