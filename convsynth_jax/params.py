"""The typed parameter tree of a run: one frozen dataclass per config group.

Defaults live in the dataclasses (each stage's ``params.py``) and nowhere else: ``config.py``
registers them as Hydra structured-config schemas that the YAML files in ``conf/<group>/`` extend,
and converts the composed config into a :class:`Params` once per task. Library functions take
these dataclasses and arrays, never a DictConfig.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Dict, Optional

from .annotate.params import AnnotateParams
from .graph.params import FeatureParams, GraphParams
from .search.params import SearchParams
from .stats.params import StatsParams
from .synth.params import SynthParams
from .systems.base import SystemParams


@dataclass(frozen=True)
class CorpusParams:
    """``conf/corpus``: which dyadic corpus (or BVH folder) a task reads."""

    kind: str = "synthetic"        # synthetic | genea | manifest | bvh_folder
    name: Optional[str] = None     # synthetic: folder name under the cache directory
    root: Optional[str] = None     # genea / bvh_folder: the folder; synthetic: None = <cache_dir>/<name>
    path: Optional[str] = None     # manifest: the YAML or CSV file
    pattern: str = "**/*.bvh"      # bvh_folder: files to read
    characters: Dict[str, str] = field(default_factory=dict)  # role -> character name (genea)
    duration_tolerance: float = 1.0  # s; motion/audio/transcript durations may differ by this much
    generator: Dict[str, Any] = field(default_factory=dict)  # synthetic: keys of data/synthetic.py DEFAULTS


@dataclass(frozen=True)
class LooParams:
    """``loo:`` in ``conf/config.yaml``: leave-one-out windows (paper Section 8)."""

    window: float = 15.0               # s
    hop: float = 14.0                  # s
    max_windows: Optional[int] = None  # first N windows only (tests, quick runs)


@dataclass(frozen=True)
class Params:
    seed: int
    cache_dir: str
    progress: bool
    corpus: CorpusParams
    features: FeatureParams
    annotate: AnnotateParams
    stats: StatsParams
    graph: GraphParams
    search: SearchParams
    synth: SynthParams
    loo: LooParams
    system: SystemParams
    extra: Dict[str, Any] = field(default_factory=dict)  # groups of other systems (walktalk, cdbn, ...)

    @property
    def fps(self) -> float:
        return float(self.features.fps)
