"""Motion-graph construction: transition-cost kernels, key states, thresholds, SCC pruning."""
from .build import build_graph, build_graph_from_clips  # noqa: F401
from .database import MotionDatabase, build_database  # noqa: F401
from .types import MotionGraph, load_graph  # noqa: F401
