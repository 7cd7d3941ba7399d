"""A search failure under the paper's rule ends with what would make motion (search/result.py: next_step),
for every caller of the registered searches (synth/pipeline.py: SEARCHES, which synthesize, leave-one-out,
the main job and converse's window chain call)."""
import dataclasses

import numpy as np

from convsynth_jax.search.params import SearchParams
from convsynth_jax.search.result import NEXT_STEP, SearchResult, explained, next_step


def failing(kind):
    def search(graph, cons, params, seed=0, start_states=None):
        return SearchResult(False, None, float("inf"), 0, 3, 0, 7, {"kind": kind, "start": 5, "end": 20}, 0.0, "beam",
                            failure=f"no path satisfies the {kind} constraint")
    return search


def test_paper_rule_failures_name_preset_quality_and_the_condition():
    paper = SearchParams()
    for kind, condition in (("PC", "none"), ("LR", "no_lr"), ("HP", "no_hp"), ("idle", "none")):
        res = explained(failing(kind))(None, None, paper, seed=1)
        assert res.failure.startswith(f"no path satisfies the {kind} constraint. {NEXT_STEP}")
        assert "preset=quality" in res.failure and f"condition {condition}" in res.failure
        assert res.failure.count(NEXT_STEP) == 1
        assert explained(lambda *a, **k: res)(None, None, paper).failure.count(NEXT_STEP) == 1   # once
    # under best effort (preset=quality) the failure is left as it is
    quality = dataclasses.replace(paper, on_failure="best_effort")
    assert next_step(quality, {"kind": "PC"}) is None
    assert explained(failing("PC"))(None, None, quality).failure == "no path satisfies the PC constraint"
    ok = SearchResult(True, np.zeros(3, np.int64), 0.0, 0, 0, 0)
    assert explained(lambda *a, **k: ok)(None, None, paper).failure is None


def test_every_registered_search_explains_its_failures():
    from convsynth_jax.synth.pipeline import SEARCHES

    for fn in SEARCHES.values():
        assert hasattr(fn, "unexplained")
