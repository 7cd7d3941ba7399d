"""The paper's system (Yang et al. 2020) behind the synthesis-system interface: a motion graph per
character built from the training sessions (Section 6), searched under the window's audio
constraints and realized (Section 7). Conditions switch the search's constraint flags
(``conf/system/motion_graph.yaml``)."""
from __future__ import annotations

import dataclasses
import logging
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Optional

import numpy as np

from ..errors import GraphError
from ..fingerprint import code_fingerprint, content_digest, stable_hash
from ..graph import load_graph
from ..graph.build import build_graph_from_clips
from ..graph.hubs import hub_costs
from ..graph.types import MotionGraph
from ..synth.pipeline import synthesize_character
from ..utils import file_lock
from .base import WindowInput, WindowResult
from .playback import PlaybackSystem, clip_name, training_labels

log = logging.getLogger(__name__)

__all__ = ["GraphModel", "MotionGraphCondition", "MotionGraphSystem", "clip_name", "graph_key"]


@dataclass
class GraphModel:
    """A character's motion graph, the clip motions its states index, and its construction time;
    labels: clip name -> (own, partner) per-frame audio labels (the independent checker's input)."""

    graph: MotionGraph
    motions: dict
    seconds: float
    labels: dict = dataclasses.field(default_factory=dict)
    # the search temperatures' factor that keeps their unit (the median synthetic edge cost of the
    # graph as built) when ``penalized_graph`` changed the costs
    temperature_scale: float = 1.0


def _read_cached_graph(path: Path):
    """The graph stored at ``path``, or None when absent or unreadable (then built again)."""
    if not path.is_file():
        return None
    try:
        return load_graph(path)
    except GraphError as e:
        log.warning("ignoring unreadable cached motion graph (%s); building it again", e)
        return None


def penalized_graph(graph: MotionGraph, transition_penalty: float = 0.0, loop_penalty: float = 0.0,
                    hub_penalty: float = 0.0, hub_cap: float = 16.0, hub_ends: str = "target"
                    ) -> tuple[MotionGraph, float]:
    """(``graph`` with penalties on its synthetic edges, temperature factor) (ours; the cached graph is
    unchanged). Each penalty is a multiple of the graph's median synthetic edge cost m:
    ``transition_penalty`` is added to every synthetic edge (a path pays for each synthetic transition,
    so it stays longer in a clip where fewer transitions meet the constraints too); ``loop_penalty``
    to every synthetic edge back to an earlier frame of the same clip (a path that loops replays the
    seconds it has just shown); ``hub_penalty`` x m x min(target's synthetic in-degree / the mean, ``hub_cap``)
    to every synthetic edge (``hub_ends="both"``: the mean of the target's and the source's relative degrees;
    graph/hubs.py: transitions spread over the recordings instead of converging
    on the near-mean states most edges enter). The searches' temperature is relative to the median synthetic cost;
    the factor (m / the new median) keeps it at the built graph's. No penalty: (graph, 1.0)."""
    syn = np.asarray(graph.synthetic, bool)
    if (float(transition_penalty) <= 0 and float(loop_penalty) <= 0 and float(hub_penalty) <= 0) or not syn.any():
        return graph, 1.0
    m = float(np.median(graph.cost[syn]))
    src = np.repeat(np.arange(graph.num_states), np.diff(graph.indptr))
    back = syn & (graph.clip[src] == graph.clip[graph.indices]) & (graph.frame[graph.indices] < graph.frame[src])
    extra = float(transition_penalty) * m * syn + float(loop_penalty) * m * back + hub_costs(graph, hub_penalty, hub_cap, hub_ends)
    cost = (np.asarray(graph.cost, np.float64) + extra).astype(graph.cost.dtype)
    new_m = float(np.median(cost[syn]))
    return dataclasses.replace(graph, cost=cost), (m / new_m if new_m > 0 else 1.0)


# the subpackages a built graph depends on (above the foundation; the import-linter layers)
GRAPH_CODE = ("io", "annotate", "stats", "data", "graph")


def graph_key(items, params, *extra) -> str:
    """The cache key of a graph built from ``items`` ((clip name, motion, own labels, partner labels)):
    the content of the clips (motion and labels, not only their names: corpora name their sessions
    alike, and a recording edited in place keeps its name), the graph, feature and annotation
    parameters, the code that builds graphs, and ``extra``."""
    clips = sorted(items, key=lambda it: it[0])
    return stable_hash([name for name, *_ in clips], [content_digest(rest) for _, *rest in clips],
                       params.graph, params.features, params.annotate, code_fingerprint(*GRAPH_CODE), *extra)


@dataclass(frozen=True)
class MotionGraphCondition:
    """One ablation condition of the motion graph (``conf/system/motion_graph.yaml``, paper Section 8):
    the search's constraint switches it sets (None: the ``search`` group's value)."""

    use_constraints: Optional[bool] = None   # any audio constraint at all
    use_lr: Optional[bool] = None            # listener-response constraints
    use_hp: Optional[bool] = None            # hesitation-pause constraints


class MotionGraphSystem(PlaybackSystem):
    condition_type = MotionGraphCondition
    produces_hands = True
    fit_procedure = "fit (graph construction)"
    synthesis_procedure = "synthesis (search)"

    def fit(self, clips, character: str, condition: str, cache_dir=None) -> GraphModel:
        """Build (or load from ``cache_dir``) the graph of ``character`` from its training clips."""
        p = self.params
        items = [(clip_name(c.session, c.role), c.motion, c.own, c.partner) for c in clips]
        motions = {name: m for name, m, _, _ in items}
        labels = training_labels(clips)
        key = graph_key(items, p)
        cached = Path(cache_dir) / f"graph_{character}_{key}.npz" if cache_dir else None
        if cached is None:
            return self._build(items, motions, labels, None)
        g = _read_cached_graph(cached)
        if g is None:  # several processes on one cache folder: the first builds, the others wait and read
            with file_lock(cached):
                g = _read_cached_graph(cached)
                if g is None:
                    return self._build(items, motions, labels, cached)
        return self.graph_model(g, motions, float(g.meta.get("seconds", np.nan)), labels)

    def graph_model(self, g, motions, seconds, labels) -> GraphModel:
        """The model of a built or loaded graph, with the configured penalties (``penalized_graph``)."""
        sp = self.params.synth
        g, scale = penalized_graph(g, sp.transition_penalty, sp.loop_penalty, sp.hub_penalty, sp.hub_cap,
                                   sp.hub_ends)
        return GraphModel(g, motions, seconds, labels, scale)

    def _build(self, items, motions, labels, cached) -> GraphModel:
        t0 = time.perf_counter()
        g = build_graph_from_clips(items, self.params.graph, self.params.features)
        seconds = time.perf_counter() - t0
        g.meta["seconds"] = seconds
        if cached is not None:
            g.save(cached)
        return self.graph_model(g, motions, seconds, labels)

    def prepare(self, models) -> None:
        """The beam search's arrays of the characters' graphs padded to one shape: one compiled search
        program for the conversation (search/beam.py: share_shapes; results unchanged)."""
        if self.params.search.method == "beam":
            from ..search.beam import share_shapes

            share_shapes([getattr(m, "graph", None) for m in models.values()], int(self.params.search.max_degree))

    def search_params(self, condition: str):
        return dataclasses.replace(self.params.search, **self.condition_options(condition))

    def synthesize(self, model: GraphModel, window: WindowInput, condition: str) -> WindowResult:
        sp = self.search_params(condition)
        k = float(getattr(model, "temperature_scale", 1.0))
        if k != 1.0:
            sp = dataclasses.replace(sp, temperature=sp.temperature * k,
                                     retry_temperatures=[t * k for t in sp.retry_temperatures])
        res = synthesize_character(model.graph, model.motions, window.own_segments, window.partner_segments,
                                   window.num_frames, sp, self.params.synth,
                                   seed=window.seed, chair_index=window.chair_index)
        diag = {"search_method": res.method, "cost": res.cost, "num_synthetic_transitions": res.num_synthetic_transitions,
                "best_effort": bool(res.best_effort), "warp": res.warp, "unmet_constraints": res.unmet}
        if res.success:
            used = np.asarray(res.transition_costs or [], dtype=np.float64)
            diag["mean_transition_cost"] = float(used.mean()) if used.size else 0.0
        return WindowResult(
            success=bool(res.success), motion=res.motion, seconds=res.search_seconds,
            constraints_total=res.constraints_total, constraints_met=res.constraints_met, failure=res.failure,
            source_clip=res.source_clip if res.success else None,
            source_frame=np.asarray(res.source_frame) if res.success else None,
            diagnostics={**diag, "blinks": res.blinks, "path": res.path, "transition_costs": res.transition_costs},
            synthetic_at=res.synthetic_at if res.success else None, blend_frames=int(self.params.synth.blend_frames))

    def motion_graph(self, model: GraphModel):
        return model.graph
