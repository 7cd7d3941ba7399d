"""The cdbn_* tasks end to end on a very small semi-synthetic corpus (speed settings only)."""
from __future__ import annotations

import json

import numpy as np
import pytest

from convsynth_jax.config import compose, run_task
from convsynth_jax.errors import CDBNError

FAST = ["cdbn.data.num_turns=24", "cdbn.train.max_iter=4", "cdbn.constrain.states_per_constraint=2",
        "cdbn.eval.folds=3", "cdbn.eval.jdbn_grid=[3]", "cdbn.eval.cdbn_grid=[2]", "cdbn.eval.max_test_folds=1",
        "cdbn.eval.fig6_states=4", "cdbn.eval.distance_max_iter=4"]


@pytest.fixture(scope="module")
def corpus_args(tmp_path_factory):
    root = tmp_path_factory.mktemp("cdbn") / "corpus"
    return [f"cdbn.corpus_root={root}", f"cache_dir={root.parent}"] + FAST


def test_make_data_and_eval(corpus_args, tmp_path):
    s = run_task(compose(["task=cdbn_make_data"] + corpus_args), tmp_path / "make")
    assert s["turns"] == 24 and s["nod_segments"] + s["shake_segments"] > 0
    out = tmp_path / "eval"
    s = run_task(compose(["task=cdbn_eval"] + corpus_args), out)
    for f in ("summary.json", "table_head.csv", "table_gestures.csv", "fig6_init.png", "fig9_states.png",
              "trajectories.png", "model_jdbn.npz", "model_cdbn.npz", "heldout.npz", "constraint_tests.json"):
        assert (out / f).is_file(), f
    summary = json.loads((out / "summary.json").read_text())
    assert {r["model"] for r in summary["table"]} == {"Baseline (jDBN)", "CDBN-Ges"}
    # the held-out log-likelihoods in the summary are those of the written models on heldout.npz
    from convsynth_jax.cdbn.em import e_step, make_batch
    from convsynth_jax.cdbn.modelio import load_model

    h = np.load(out / "heldout.npz")
    for kind in ("jdbn", "cdbn"):
        z = np.load(out / f"model_{kind}.npz")
        K, D = z["means"].shape
        assert z["covariances"].shape == (K, D, D) and z["transitions"].shape[1:] == (K, K)
        assert z["initial"].shape[0] == (1 if kind == "jdbn" else 3)
        model, _ = load_model(out / f"model_{kind}.npz")
        b = make_batch([h["observations"]], [h["constraints"]] if kind == "cdbn" else None, max_length=None)
        ll = e_step(model, b).log_likelihood / len(h["observations"])
        assert ll == pytest.approx(summary["models"][kind]["heldout_loglik_per_frame"], rel=1e-4)


def test_synthesize_real_speech_with_constraints(corpus_args, tmp_path, speech_dir):
    from convsynth_jax.io.audio import load_audio
    from convsynth_jax.io.bvh import load_bvh

    wav = speech_dir / "acoustic_corpus.wav"
    tsv = tmp_path / "c.tsv"
    tsv.write_text("start\tend\tlabel\n2.0\t3.5\tnod\n6.0\t7.0\tshake\n")
    s = run_task(compose(["task=cdbn_synthesize", f"task.audio={wav}", f"task.constraints={tsv}"] + corpus_args),
                 tmp_path / "syn")
    mo = load_bvh(s["bvh"])
    assert mo.num_frames == round(load_audio(wav).duration * 30)
    assert s["constraint_frames"]["nod"] == 45 and s["constraint_frames"]["shake"] == 30
    bad = tmp_path / "bad.tsv"
    bad.write_text("2.0\t3.5\tnod\n3.0\t4.0\tnod\n")
    with pytest.raises(CDBNError, match="line 2"):
        run_task(compose(["task=cdbn_synthesize", f"task.audio={wav}", f"task.constraints={bad}"] + corpus_args),
                 tmp_path / "syn2")


def test_eval_with_the_hand_model_on_real_bandai_clips(corpus_args, tmp_path):
    """cdbn.eval.hands: the hand model (Table V analogue) on real Bandai2 raise/wave clips with real speech."""
    import shutil

    from conftest import shared_path

    src, wav = shared_path("bandai2", "bvh"), shared_path("speech", "acoustic_corpus.wav")
    clips = tmp_path / "bvh"
    clips.mkdir()
    for kind in ("raise-up-right-hand", "wave-right-hand"):
        for f in sorted(src.glob(f"*_{kind}_normal_0*.bvh"))[:5]:
            shutil.copy(f, clips / f.name)
    out = tmp_path / "eval"
    run_task(compose(["task=cdbn_make_data"] + corpus_args), tmp_path / "make")
    s = run_task(compose(["task=cdbn_eval"] + corpus_args + [
        f"cdbn.eval.hands.bvh_dir={clips}", f"cdbn.eval.hands.wav={wav}",
        "cdbn.eval.hands.eval.folds=3", "cdbn.eval.hands.eval.jdbn_grid=[3]", "cdbn.eval.hands.eval.cdbn_grid=[2]",
        "cdbn.eval.hands.eval.max_test_folds=1"]), out)
    assert (out / "table_hands.csv").is_file()
    h = s["hands"]
    assert h["turns"] == 10 and set(h["frames_per_constraint"]) == {"other", "raise-up-right-hand", "wave-right-hand"}
    assert {r["model"] for r in h["table"]} == {"Baseline (jDBN)", "CDBN-Ges"}
    for r in h["table"]:
        assert np.isfinite([r["cca_m_mean"], r["cca_ms_mean"], r["kld"]]).all()
