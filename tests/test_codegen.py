"""The suite compiles with XLA's older CPU fusion emitters (``SUITE_XLA_FLAG`` in conftest.py, for
compile time); the control: kernels of each method give the same results under XLA's default code
generation, computed in a child process that runs with the default emitters."""
from __future__ import annotations

import os
import subprocess
import sys

import numpy as np

from conftest import REPO, SUITE_XLA_FLAG, TEST_DATA

CHILD = """
import os, sys
import numpy as np
sys.path.insert(0, os.path.join(sys.argv[1], "tests"))
from test_codegen import kernel_outputs
np.savez(sys.argv[2], flags=os.environ["XLA_FLAGS"], **kernel_outputs())
"""


def kernel_outputs() -> dict:
    """Forward kinematics of a real clip, a look-ahead beam search on a random graph, and the CDBN
    smoother's posteriors of random sequences (float32, as the methods run them)."""
    import jax.numpy as jnp

    from convsynth_jax.cdbn.em import make_batch
    from convsynth_jax.cdbn.hmm import batch_posterior
    from convsynth_jax.io.bvh import load_bvh
    from convsynth_jax.kinematics import fk_kernel
    from convsynth_jax.search.beam import beam_search
    from convsynth_jax.search.constraints import build_constraints
    from convsynth_jax.search.params import SearchParams
    from test_cdbn_hmm import random_model, sample     # as the other tests import them: one module each
    from test_search_beam_kernel import FPS, hub_graph, input_from_clip

    m = load_bvh(sorted(TEST_DATA.glob("*.bvh"))[0])
    pos, rot = fk_kernel(jnp.asarray(m.rotations, jnp.float32), jnp.asarray(m.translations, jnp.float32),
                         m.skeleton.parents)
    g, audio = hub_graph(np.random.default_rng(0))
    own, par = input_from_clip(audio, "c0", 40)
    cfg = SearchParams(tolerance=0.1, beam_size=32, max_candidates=48, max_degree=24, matching="labels")
    res = beam_search(g, build_constraints(own, par, 40, FPS, cfg), cfg, seed=0)
    rng = np.random.default_rng(1)
    model = random_model(rng)
    seqs, cons = zip(*[sample(rng, model, T) for T in (37, 60)])
    b = make_batch(seqs, cons, bucket=16)
    post = batch_posterior(jnp.asarray(b.x), jnp.asarray(b.constraints), jnp.asarray(b.lengths),
                           *(jnp.asarray(a, jnp.float32) for a in (model.means, model.covariances, model.initial,
                                                                   model.transitions)), (0, 1, 2, 3))
    return {"fk_positions": np.asarray(pos), "fk_rotations": np.asarray(rot), "search_path": np.asarray(res.path),
            "search_cost": np.float64(res.cost), "hmm_loglik": np.asarray(post.log_likelihood),
            "hmm_smoothed": np.asarray(post.smoothed)}


def test_kernels_give_the_same_results_under_the_default_code_generation(tmp_path):
    assert SUITE_XLA_FLAG in os.environ["XLA_FLAGS"]          # this process compiles with the suite's flag
    default = os.environ["XLA_FLAGS"].replace(SUITE_XLA_FLAG, "--xla_cpu_use_fusion_emitters=true")
    env = dict(os.environ, XLA_FLAGS=default)
    env.pop("CONVSYNTH_JAX_CACHE", None)                      # compile afresh: no executable of this run's
    out = tmp_path / "default.npz"
    r = subprocess.run([sys.executable, "-c", CHILD, str(REPO), str(out)], env=env, cwd=REPO,
                       capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stderr[-3000:]
    theirs = np.load(out)
    assert "fusion_emitters=true" in str(theirs["flags"])
    ours = kernel_outputs()
    np.testing.assert_array_equal(theirs["search_path"], ours["search_path"])   # the same path, exactly
    np.testing.assert_allclose(theirs["search_cost"], ours["search_cost"], rtol=1e-6)
    for name in ("fk_positions", "fk_rotations", "hmm_loglik", "hmm_smoothed"):
        np.testing.assert_allclose(theirs[name], ours[name], rtol=1e-5, atol=1e-6, err_msg=name)
