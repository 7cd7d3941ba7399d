"""The typed parameter tree of a run: one frozen dataclass per config group.

Defaults live in the dataclasses (each stage's ``params.py``) and nowhere else. ``config.py``
converts the composed config into a :class:`Params` once per task, group by group, with the one
conversion function :func:`convsynth_jax.schema.build_params`; library functions take these
dataclasses and arrays, never the configuration objects of Hydra.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Dict, Optional

from .annotate.params import AnnotateParams
from .cdbn.params import CDBNParams
from .graph.params import FeatureParams, GraphParams
from .kernel_cache import JaxCacheParams
from .search.params import SearchParams
from .stats.params import StatsParams
from .synth.params import SynthParams
from .systems.base import SystemParams
from .walktalk.params import WalkTalkParams


@dataclass(frozen=True)
class CorpusParams:
    """``conf/corpus``: which dyadic corpus (or BVH folder) a task reads."""

    kind: str = "synthetic"        # synthetic | genea | manifest | bvh_folder | beat2
    name: Optional[str] = None     # synthetic: folder name under the cache directory
    root: Optional[str] = None     # genea / bvh_folder: the folder; synthetic: None = <cache_dir>/<name>
    path: Optional[str] = None     # manifest: the YAML or CSV file
    pattern: str = "**/*.bvh"      # bvh_folder: files to read
    characters: Dict[str, str] = field(default_factory=dict)  # role -> character name (every dyadic loader; wins over corpus.json)
    duration_tolerance: float = 1.0  # s; motion/audio/transcript durations may differ by this much
    # beat2: how single-speaker takes become sessions (io/beat2.py; partner statistics are a null control)
    pairing: str = "pseudo_dyad"
    pseudo_shift_s: Optional[float] = None   # beat2: time shift of a take's pseudo-partner copy (None: half the take)
    smplx_model: Optional[str] = None        # beat2: the user's SMPL-X model file (exact rest joints; None: template)
    # synthetic: the generator's keys that differ from its defaults (data/synthetic/config.py:
    # GeneratorParams; checked by generator_params when the config is converted)
    generator: Dict[str, Any] = field(default_factory=dict)

    def __post_init__(self):
        if self.generator:
            from .data.synthetic.config import generator_params

            generator_params(self.generator)


@dataclass(frozen=True)
class LooParams:
    """``loo:`` in ``conf/config.yaml``: leave-one-out windows (paper Section 8)."""

    window: float = 15.0               # s
    hop: float = 14.0                  # s
    max_windows: Optional[int] = None  # first N windows only (tests, quick runs)


@dataclass(frozen=True)
class Params:
    """Every group of a run's config (``conf/config.yaml``), typed."""

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
    cdbn: CDBNParams = field(default_factory=CDBNParams)
    walktalk: WalkTalkParams = field(default_factory=WalkTalkParams)
    jax_cache: JaxCacheParams = field(default_factory=JaxCacheParams)

    @property
    def fps(self) -> float:
        return float(self.features.fps)
