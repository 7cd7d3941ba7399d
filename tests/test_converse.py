"""task=converse: a whole conversation of new speech -> both characters' motion, windows chained
without seams (convsynth_jax/synth/chain.py, convsynth_jax/tasks/converse.py), and the searches'
start-state argument it relies on."""
import json
import threading

import numpy as np
import pandas as pd
import pytest

from convsynth_jax.config import compose, run_task
from convsynth_jax.errors import AudioFormatError, ConfigError, MissingFileError, SearchFailure, TranscriptFormatError
from convsynth_jax.search.beam import beam_search
from convsynth_jax.search.check import check_path
from convsynth_jax.search.constraints import build_constraints
from convsynth_jax.search.dfs import stochastic_greedy_search
from convsynth_jax.search.params import SearchParams
from convsynth_jax.synth.chain import at_steps, excess_acceleration, plan_windows, quiet_mask, successors

from test_search_beam_kernel import FPS, hub_graph, input_from_clip

SECONDS = 30.0
# short windows, and the beam of preset=paper (256 paths): these tests check the chaining, the reports and the
# errors, whose figures (e.g. the seams the control shows at cuts) were set on those paths; preset=quality's
# wider beam is tested by the search tests and measured by experiments/bench/bench_converse.py
FAST = ["task.window_s=10", "task.hop_s=8", "task.snap_s=1", "task.min_last_s=5", "task.video_fps=5",
        "search.beam_size=256", "search.max_candidates=2048"]


# ---------------------------------------------------------------------------------------------- the searches
@pytest.mark.parametrize("search", ["beam", "dfs"])
@pytest.mark.parametrize("seed", range(3))
def test_start_states_restrict_the_first_state(search, seed):
    rng = np.random.default_rng(seed)
    g, audio = hub_graph(rng)
    own, par = input_from_clip(audio, f"c{seed}", 40)
    cfg = SearchParams(beam_size=32, max_candidates=512, max_degree=24, retry_temperatures=[], retry_beam_size=0,
                       method=search)
    cons = build_constraints(own, par, 40, FPS, cfg)
    fn = beam_search if search == "beam" else stochastic_greedy_search
    free = fn(g, cons, cfg, seed=seed)
    assert free.success
    # every state allowed: the same search as without the argument
    np.testing.assert_array_equal(fn(g, cons, cfg, seed=seed, start_states=np.arange(g.num_states)).path, free.path)
    # one allowed state that can complete the window: the path starts there
    s0 = int(free.path[0])
    other = fn(g, cons, cfg, seed=seed + 1, start_states=[s0])
    assert other.success and int(other.path[0]) == s0
    # the successors of a state (how a chained window starts): the path starts among them, constraints met
    succ = successors(g, int(free.path[5]), cfg.max_degree)
    res = fn(g, cons, cfg, seed=seed, start_states=succ)
    if res.success:
        assert int(res.path[0]) in set(succ.tolist())
        rep = check_path([g.clip_names[g.clip[s]] for s in res.path], [int(g.frame[s]) for s in res.path], audio,
                         own, par, FPS, cfg.tolerance)
        assert rep["met"] == rep["total"]
    # no allowed state: fails at frame 0
    none = fn(g, cons, cfg, seed=seed, start_states=np.zeros(0, np.int64))
    assert not none.success and none.failed_frame == 0


def test_successors_are_the_cheapest_out_edges():
    g, _ = hub_graph(np.random.default_rng(3))
    for s in range(0, g.num_states, 17):
        tg, cost, _ = g.out_edges(s)
        got = successors(g, s, 3)
        assert len(got) == min(3, len(tg))
        assert np.all(np.sort(cost[np.isin(tg, got)])[:len(got)] <= np.sort(cost)[len(got) - 1] + 1e-9)


# ---------------------------------------------------------------------------------------------- windows
def test_plan_covers_the_input_and_moves_cuts_to_pauses():
    fps = 30.0
    seg = pd.DataFrame({"kind": ["PC", "PC"], "start": [11.5, 30.0], "end": [12.6, 31.0]})  # speech over the 12 s cut
    T = int(47.3 * fps)
    quiet = quiet_mask([seg], T, fps, 3)
    plan = plan_windows(T, fps, 15.0, 12.0, 1.5, 5.0, quiet)
    assert plan[0].start == 0 and plan[-1].end == T
    assert all(a.end == b.start for a, b in zip(plan[:-1], plan[1:]))           # contiguous, no gap or overlap
    assert all(w.start < w.end <= w.search_end <= w.start + int(15 * fps) or w is plan[-1] for w in plan)
    assert quiet[plan[0].end] and plan[0].end < int(11.5 * fps)               # moved back before the clause
    assert plan[-1].end - plan[-1].start <= int((15 + 5) * fps)
    # without pauses nearby the cut stays at the hop
    assert plan_windows(T, fps, 15.0, 12.0, 1.5, 5.0, np.zeros(T, bool))[0].end == int(12 * fps)
    # short inputs: one window
    assert len(plan_windows(300, fps, 15.0, 12.0)) == 1
    with pytest.raises(ConfigError, match="hop"):
        plan_windows(T, fps, 10.0, 12.0)


# ---------------------------------------------------------------------------------------------- the task
@pytest.fixture(scope="module")
def cache(tiny_cache_dir):
    return tiny_cache_dir("converse_cache")


@pytest.fixture(scope="module")
def inputs(tiny_corpus_dir, tmp_path_factory):
    """The first SECONDS of session01's two participants (the tiny corpus's own audio and words)."""
    from convsynth_jax.io import load_audio, load_transcript, save_wav
    from convsynth_jax.io.transcripts import save_transcript_tsv

    d = tmp_path_factory.mktemp("converse_in")
    out = {}
    for role, x in (("main-agent", "a"), ("interloctr", "b")):
        a = load_audio(tiny_corpus_dir / f"session01_{role}.wav")
        n = int(SECONDS * a.sample_rate)
        save_wav(d / f"{x}.wav", a.samples[:n], a.sample_rate)
        w = load_transcript(tiny_corpus_dir / f"session01_{role}.tsv")
        save_transcript_tsv(w[w["end"] <= SECONDS].reset_index(drop=True), d / f"{x}.tsv")
        out[f"audio_{x}"], out[f"transcript_{x}"] = d / f"{x}.wav", d / f"{x}.tsv"
    return out


def converse_cfg(tiny_corpus_dir, cache, inputs, *extra):
    return compose(["task=converse", "corpus=synthetic_tiny", f"corpus.root={tiny_corpus_dir}", f"cache_dir={cache}",
                    "progress=false", *[f"task.{k}={v}" for k, v in inputs.items()], *FAST, *extra])


@pytest.fixture(scope="module")
def chained(tiny_corpus_dir, cache, inputs, tmp_path_factory):
    out = tmp_path_factory.mktemp("converse_out")
    return out, run_task(converse_cfg(tiny_corpus_dir, cache, inputs), out)


@pytest.fixture(scope="module")
def independent(tiny_corpus_dir, cache, inputs, chained, tmp_path_factory):
    out = tmp_path_factory.mktemp("converse_seams")
    return out, run_task(converse_cfg(tiny_corpus_dir, cache, inputs, "task.chaining=independent", "task.video=false"), out)


def test_characters_one_after_the_other_give_the_same_bytes(chained, tiny_corpus_dir, cache, inputs, tmp_path):
    """A and B are searched and realized in two threads by default; one after the other gives the same files."""
    out, _ = chained
    run_task(converse_cfg(tiny_corpus_dir, cache, inputs, "task.video=false", "task.parallel_characters=false"), tmp_path)
    for name in ("A.bvh", "B.bvh", "A_blinks.csv", "B_blinks.csv"):
        assert (tmp_path / name).read_bytes() == (out / name).read_bytes(), name


def test_outputs_cover_the_audio(chained, inputs):
    from convsynth_jax.io import load_audio, load_bvh
    from convsynth_jax.render import probe_streams

    out, s = chained
    dur = load_audio(inputs["audio_a"]).duration
    assert s["success"] and s["windows"] >= 3
    for who in "AB":
        m = load_bvh(out / f"{who}.bvh")
        assert abs(m.num_frames - dur * m.fps) <= 1.0
        assert len(pd.read_csv(out / f"{who}_blinks.csv")) == m.num_frames
    rep = json.loads((out / "report.json").read_text())
    assert "| character | window |" in (out / "report.md").read_text()
    for who, ch in rep["characters"].items():
        # every window reported, checked by the independent checker; the whole path re-checked too
        assert [w["index"] for w in ch["windows"]] == [w["index"] for w in ch["checker"]["windows"]]
        assert ch["windows"][0]["start"] == 0 and ch["windows"][-1]["end"] == rep["inputs"]["num_frames"]
        tot = ch["checker"]["total"]
        assert tot["total"] > 0 and sum(k["total"] for k in tot["by_kind"].values()) == tot["total"]
        assert s["constraints_met"][who] == tot["met"]
    v = probe_streams(out / "conversation.mp4")
    assert v["video"] == 1 and v["audio"] == 1 and abs(v["duration"] - dur) < 0.5


def test_windows_chain_without_seams_and_the_control_shows_them(chained, independent, tiny_corpus_dir, cache):
    """The step across each cut is an edge of the graph and shows no more excess acceleration (realized
    minus the source clip's own) than the synthetic transitions inside windows; realizing each window
    on its own (the control) puts a seam at the cuts, which the same metric shows."""
    out, _ = chained
    rep = json.loads((out / "report.json").read_text())
    ctl = json.loads((independent[0] / "report.json").read_text())
    inner = [c["continuity"]["at_synthetic_transitions_max"] for c in rep["characters"].values()]
    inner = max([x for x in inner if x is not None] + [0.0])
    chained_cuts, control_cuts = [], []
    for who in "AB":
        cont = rep["characters"][who]["continuity"]
        assert len(cont["at_cuts"]) == len(rep["characters"][who]["windows"]) - 1 >= 2
        chained_cuts += list(cont["at_cuts"].values())
        control_cuts += list(ctl["characters"][who]["continuity"]["at_cuts"].values())
    assert max(chained_cuts) <= inner + 1e-3, (chained_cuts, inner)
    assert max(control_cuts) > 3 * max(inner, 0.1), (control_cuts, inner)
    # the same metric recomputed from the written BVH: the root trajectory has no jump at a cut
    from convsynth_jax.io import load_bvh

    for who in "AB":
        root = load_bvh(out / f"{who}.bvh").root_positions
        step = np.linalg.norm(np.diff(root, axis=0), axis=-1)
        cuts = [int(t) for t in rep["characters"][who]["cuts"]]
        others = np.delete(step, [t - 1 for t in cuts])
        assert max(step[t - 1] for t in cuts) <= others.max() + 1e-6
        croot = load_bvh(independent[0] / f"{who}.bvh").root_positions
        cstep = np.linalg.norm(np.diff(croot, axis=0), axis=-1)
        assert max(cstep[t - 1] for t in cuts) > 2 * max(step[t - 1] for t in cuts) + 1e-3


def test_excess_acceleration_is_zero_along_a_clip_and_shows_a_jump(tiny_corpus_dir):
    from convsynth_jax.io import load_bvh

    n = int(SECONDS * 30)   # the conversation's length: forward kinematics compiled once for both
    full = load_bvh(tiny_corpus_dir / "session01_main-agent.bvh")
    m = full.slice(0, n)
    clips, frames = ["c"] * n, list(range(n))
    prof = excess_acceleration(m, {"c": full}, clips, frames)
    assert prof.max() < 1e-3
    jumped = list(range(n // 2)) + list(range(n // 2 + 30, n + 30))   # the same clip played with a 30-frame jump
    realized = type(m)(m.skeleton, full.rotations[jumped], full.translations[jumped], m.fps)
    prof = excess_acceleration(realized, {"c": full}, clips, jumped)
    assert at_steps(prof, [n // 2])[n // 2] > 10 * max(prof[:n // 2 - 5].max(), 1e-3)


def _video_frames(path):
    """(frames per second, RGB frames (H, W, 3) uint8) of an MP4, decoded by imageio-ffmpeg."""
    import imageio_ffmpeg

    reader = imageio_ffmpeg.read_frames(str(path))
    meta = next(reader)
    w, h = meta["size"]
    return meta["fps"], [np.frombuffer(f, np.uint8).reshape(h, w, 3) for f in reader]


def test_video_never_colours_a_body_as_a_transition(chained):
    """Synthetic transitions are ticks on the timeline: at the video frames nearest each transition
    no pixel above the timeline is transition red (the figures used to turn red there, both at once
    when the characters' transitions fell close together)."""
    out, _ = chained
    rep = json.loads((out / "report.json").read_text())
    fps, frames = _video_frames(out / "conversation.mp4")
    step = 30.0 / fps
    near = sorted({min(int(round(t["frame"] / step)), len(frames) - 1)
                   for w in "AB" for t in rep["characters"][w]["transitions"]})
    assert len(near) >= 3
    for i in near:
        top = frames[i][: int(0.6 * frames[i].shape[0])].astype(int)
        red = (top[..., 0] > 170) & (top[..., 1] < 80) & (top[..., 2] < 80)
        assert red.sum() == 0, (i, int(red.sum()))


def test_video_keeps_the_timeline_labels_inside_the_frame(chained):
    """The speakers' names beside the timeline are inside the frame: no text (dark pixels) in the
    three columns at either edge (they used to be cut off at the left edge)."""
    out, _ = chained
    _, frames = _video_frames(out / "conversation.mp4")
    for img in (frames[0], frames[-1]):
        dark = img.astype(int).sum(-1) < 300
        assert not dark[:, :3].any() and not dark[:, -3:].any(), np.nonzero(dark[:, :3].any(1))[0][:10]


def test_missing_or_malformed_input_names_the_file(tiny_corpus_dir, cache, inputs, tmp_path):
    def run(**over):
        return run_task(converse_cfg(tiny_corpus_dir, cache, {**inputs, **over}), tmp_path / "o")

    with pytest.raises(MissingFileError, match="nope.wav"):
        run(audio_b=tmp_path / "nope.wav")
    bad = tmp_path / "bad.tsv"
    bad.write_text("0.1\t0.5\thello\n0.6\tx\tworld\n")
    with pytest.raises(TranscriptFormatError, match="bad.tsv.*line 2"):
        run(transcript_a=bad)
    late = tmp_path / "late.tsv"
    late.write_text(f"0.1\t0.5\thello\n{SECONDS + 3}\t{SECONDS + 4}\tworld\n")
    with pytest.raises(TranscriptFormatError, match="late.tsv.*after the end of its audio"):
        run(transcript_b=late)
    with pytest.raises(AudioFormatError, match="a.wav.*two channels"):
        run_task(converse_cfg(tiny_corpus_dir, cache, {"stereo": inputs["audio_a"], "transcript_a": inputs["transcript_a"],
                                                       "transcript_b": inputs["transcript_b"]}), tmp_path / "o")
    with pytest.raises(ConfigError, match="task.audio_b"):
        run_task(converse_cfg(tiny_corpus_dir, cache, {k: v for k, v in inputs.items() if k != "audio_b"}), tmp_path / "o")
    with pytest.raises(ConfigError, match="window_s"):
        run_task(converse_cfg(tiny_corpus_dir, cache, inputs, "task.window_s=long"), tmp_path / "o")


def test_stereo_input_gives_the_same_conversation(chained, tiny_corpus_dir, cache, inputs, tmp_path):
    from convsynth_jax.io import load_audio, save_wav

    a, b = load_audio(inputs["audio_a"]), load_audio(inputs["audio_b"])
    save_wav(tmp_path / "ab.wav", np.stack([a.samples, b.samples], axis=1), a.sample_rate)
    s = run_task(converse_cfg(tiny_corpus_dir, cache, {"stereo": tmp_path / "ab.wav", "transcript_a": inputs["transcript_a"],
                                                       "transcript_b": inputs["transcript_b"]}, "task.video=false"),
                 tmp_path / "o")
    assert s["constraints_met"] == chained[1]["constraints_met"]
    assert (tmp_path / "o" / "A.bvh").read_text() == (chained[0] / "A.bvh").read_text()


def test_report_of_one_window_without_transitions_reads_as_such(chained, tmp_path):
    """A conversation searched in one window has no cuts (and a still path no transitions): the report
    says so instead of printing nan."""
    from convsynth_jax.tasks.converse import write_report_md

    rep = json.loads((chained[0] / "report.json").read_text())
    for ch in rep["characters"].values():
        ch["continuity"]["at_cuts"], ch["continuity"]["at_synthetic_transitions_max"] = {}, None
    write_report_md(tmp_path / "report.md", rep)
    text = (tmp_path / "report.md").read_text()
    assert "nan" not in text and text.count("– (one window)") == 2 and text.count("– (none)") == 2


def test_one_speaker_alone_gives_a_silent_partner(tiny_corpus_dir, cache, inputs, tmp_path):
    """Only A's speech given (no task.audio_b, no task.transcript_b): B listens in silence for the whole
    of it, exactly as with a silent WAV and an empty transcript given for B."""
    from convsynth_jax.io import load_audio, save_wav

    a = load_audio(inputs["audio_a"])
    save_wav(tmp_path / "silent.wav", np.zeros(a.num_samples), a.sample_rate)
    (tmp_path / "empty.tsv").write_text("start\tend\tword\n")
    alone = {"audio_a": inputs["audio_a"], "transcript_a": inputs["transcript_a"]}
    s = run_task(converse_cfg(tiny_corpus_dir, cache, alone, "task.video=false"), tmp_path / "alone")
    given = {**alone, "audio_b": tmp_path / "silent.wav", "transcript_b": tmp_path / "empty.tsv"}
    s2 = run_task(converse_cfg(tiny_corpus_dir, cache, given, "task.video=false"), tmp_path / "given")
    assert s["success"] and s["constraints_total"] == s2["constraints_total"]
    for who in "AB":
        assert (tmp_path / "alone" / f"{who}.bvh").read_text() == (tmp_path / "given" / f"{who}.bvh").read_text()
    rep = json.loads((tmp_path / "alone" / "report.json").read_text())
    assert {c["kind"] for c in _constraints(rep, "B")} <= {"idle", "PH"} and rep["inputs"]["B"]["audio"] == "(silent)"


def test_a_window_without_a_path_fails_naming_it_after_writing_the_report(chained, tiny_corpus_dir, cache, inputs,
                                                                          tmp_path, monkeypatch):
    import convsynth_jax.synth.pipeline as pipeline
    from convsynth_jax.search.result import SearchResult

    real = pipeline.SEARCHES["beam"]
    calls = {}   # thread -> its calls (the two characters are searched side by side)

    def failing_second_window(graph, cons, params, seed=0, start_states=None):
        calls.setdefault(threading.current_thread().name, []).append(start_states is None)
        if start_states is not None:   # every window after the first: no path
            return SearchResult(False, None, float("inf"), 0, cons.total, 0, 0, None, 0.0, "beam", failure="stub: no path")
        return real(graph, cons, params, seed=seed, start_states=start_states)

    monkeypatch.setitem(pipeline.SEARCHES, "beam", failing_second_window)
    if hasattr(SearchParams(), "on_failure"):
        extra = ["search.on_failure=fail"]
    else:
        extra = []
    with pytest.raises(SearchFailure, match=r"window 1 \(\d+\.\d\d-\d+\.\d\d s"):
        run_task(converse_cfg(tiny_corpus_dir, cache, inputs, "task.video=false", *extra), tmp_path)
    rep = json.loads((tmp_path / "report.json").read_text())
    a = rep["characters"]["A"]
    assert not rep["success"] and [w["status"] for w in a["windows"]][:2] == ["ok", "failed"]
    assert all(w["status"] == "not_searched" for w in a["windows"][2:])
    assert a["windows"][1]["attempts"] == 3           # from the previous path's end, then 2 s and 5 s earlier
    assert "window 1" in (tmp_path / "report.md").read_text()
    assert not (tmp_path / "A.bvh").exists()
    # each character: the first window starts anywhere, the next from successors (3 tries); then the task stops
    assert sorted(calls.values()) == [[True, False, False, False]] * 2


def test_given_graph_folder(chained, tiny_corpus_dir, cache, inputs, tmp_path):
    import shutil

    (tmp_path / "g").mkdir()
    for ch in ("female", "male"):   # the graphs fitted on the whole corpus, as task=build_graph names them
        shutil.copy(next((cache / "loo_cache").glob(f"graph_{ch}_*.npz")), tmp_path / "g" / f"graph_{ch}.npz")
    s = run_task(converse_cfg(tiny_corpus_dir, cache, inputs, f"task.graphs={tmp_path / 'g'}", "task.video=false"),
                 tmp_path / "o")
    assert s["success"] and s["constraints_met"] == chained[1]["constraints_met"]
    assert (tmp_path / "o" / "B.bvh").read_text() == (chained[0] / "B.bvh").read_text()
    with pytest.raises(MissingFileError, match="nowhere"):
        run_task(converse_cfg(tiny_corpus_dir, cache, inputs, f"task.graphs={tmp_path / 'nowhere'}"), tmp_path / "o2")
    # task=synthesize reads the same graph files (one function for both tasks)
    s = run_task(compose(["task=synthesize", "corpus=synthetic_tiny", f"corpus.root={tiny_corpus_dir}", f"cache_dir={cache}",
                          "progress=false", "preset=quality",
                          *[f"+task.graphs.{ch}={tmp_path / 'g' / f'graph_{ch}.npz'}" for ch in ("female", "male")]]),
                 tmp_path / "o3")
    with pytest.raises(ConfigError, match="system=motion_graph"):   # graph files for a system without graphs
        run_task(compose(["task=synthesize", "corpus=synthetic_tiny", f"corpus.root={tiny_corpus_dir}", f"cache_dir={cache}",
                          "progress=false", "system=random_playback", "task.condition=none",
                          *[f"+task.graphs.{ch}={tmp_path / 'g' / f'graph_{ch}.npz'}" for ch in ("female", "male")]]),
                 tmp_path / "o4")
    rep = json.loads((tmp_path / "o3" / "report.json").read_text())
    from convsynth_jax.graph import load_graph

    assert s["success"] and {ch: rep["characters"][ch]["graph"]["num_states"] for ch in ("female", "male")} == \
        {ch: load_graph(tmp_path / "g" / f"graph_{ch}.npz").num_states for ch in ("female", "male")}


def test_only_motion_graph_systems(tiny_corpus_dir, cache, inputs, tmp_path):
    with pytest.raises(ConfigError, match="system=motion_graph"):
        run_task(converse_cfg(tiny_corpus_dir, cache, inputs, "system=random_playback"), tmp_path)


def test_a_system_that_reads_the_audio_alone_converses_without_a_transcript(tiny_corpus_dir, cache, inputs, tmp_path):
    """system=flow_matching (converses_from_audio): two WAVs and no transcript give two BVH as long as the
    audio, nothing recognized, and a report that says the constraints were neither enforced nor checked
    (a tiny model: what is tested is the task's wiring, not the motion)."""
    from convsynth_jax.io import load_audio, load_bvh

    tiny = ["width=16", "blocks=2", "time_embedding=8", "train_steps=20", "batch_size=8", "log_every=10",
            "window_frames=16", "prefix_frames=4", "sample_steps=2", "pca_max_components=8"]
    audio = {k: v for k, v in inputs.items() if k.startswith("audio")}
    s = run_task(converse_cfg(tiny_corpus_dir, cache, audio, "system=flow_matching", "task.video=false",
                              *[f"system.options.{o}" for o in tiny]), tmp_path)
    assert s["success"] and s["all_constraints_met"] is None and s["condition"] == "audio"
    seconds = load_audio(inputs["audio_a"]).duration
    for who in "AB":
        m = load_bvh(tmp_path / f"{who}.bvh")
        assert m.num_frames == int(round(seconds * m.fps)) and np.isfinite(np.asarray(m.rotations)).all()
        assert not (tmp_path / f"words_{who}.tsv").exists()
    report = json.loads((tmp_path / "report.json").read_text())
    assert report["inputs"]["A"]["words"] == "none" and "not enforced" in report["constraints"]



@pytest.mark.parametrize("seed", range(2))
def test_lookahead_from_start_states_agrees_with_the_kernel(seed):
    """beam.lookahead(start_states=...): solvable from the allowed states exactly when the beam's own
    look-ahead program (which masks its frame-0 states) says so; best effort relaxes from them."""
    from convsynth_jax.search.beam import _beam_search_once, lookahead

    rng = np.random.default_rng(seed)
    g, audio = hub_graph(rng)
    own, par = input_from_clip(audio, f"c{seed}", 40)
    cfg = SearchParams(beam_size=32, max_candidates=512, max_degree=24, retry_temperatures=[], retry_beam_size=0)
    cons = build_constraints(own, par, 40, FPS, cfg)
    assert lookahead(g, cons, cfg.max_degree)[1]
    for s in rng.choice(g.num_states, 12, replace=False):
        ok = lookahead(g, cons, cfg.max_degree, [int(s)])[1]
        _, _, kernel_ok = _beam_search_once(g, cons, cfg, seed, cfg.temperature, lookahead=True, start_states=[int(s)])
        assert ok == kernel_ok
    assert not lookahead(g, cons, cfg.max_degree, np.zeros(0, np.int64))[1]


# ------------------------------------------------------------------ hard inputs: cuts in clauses, silence, overlap
MIXED_S = 48.0


@pytest.fixture(scope="module")
def mixed(tiny_corpus_dir, cache, tmp_path_factory):
    """A conversation built from the tiny corpus's speech: A speaks 0-14 s, B from 11 s (3 s of overlap)
    to 23 s, both are silent for 15 s, then A speaks again from 38 s. Chained in 10 s windows (8 s kept),
    so cuts fall inside clauses."""
    from convsynth_jax.io import load_audio, load_transcript, save_wav
    from convsynth_jax.io.transcripts import save_transcript_tsv

    def piece(session, a, b):
        au = load_audio(tiny_corpus_dir / f"{session}_main-agent.wav")
        w = load_transcript(tiny_corpus_dir / f"{session}_main-agent.tsv")
        r = au.sample_rate
        w = w[(w["start"] >= a) & (w["end"] <= b)].copy()
        w["start"] -= a
        w["end"] -= a
        return np.asarray(au.samples[int(a * r):int(b * r)], float), w, r

    def place(parts):
        r = parts[0][0][2]
        buf, words = np.zeros(int(MIXED_S * r)), []
        for (x, w, _), at in parts:
            k = int(at * r)
            buf[k:k + len(x)] = x
            words.append(w.assign(start=w["start"] + at, end=w["end"] + at))
        return buf, pd.concat(words).sort_values("start").reset_index(drop=True), r

    d = tmp_path_factory.mktemp("converse_mixed")
    ins = {}
    for x, parts in (("a", [(piece("session01", 0, 14), 0.0), (piece("session01", 14, 24), 38.0)]),
                     ("b", [(piece("session02", 0, 12), 11.0)])):
        buf, w, r = place(parts)
        save_wav(d / f"{x}.wav", buf, r)
        save_transcript_tsv(w, d / f"{x}.tsv")
        ins[f"audio_{x}"], ins[f"transcript_{x}"] = d / f"{x}.wav", d / f"{x}.tsv"
    out = d / "out"
    s = run_task(converse_cfg(tiny_corpus_dir, cache, ins, "task.video=false"), out)
    return out, s, json.loads((out / "report.json").read_text())


def test_hard_inputs_succeed_with_default_settings(mixed):
    """The default preset makes motion for the whole input and the checker confirms the clauses."""
    from convsynth_jax.io import load_bvh

    out, s, rep = mixed
    assert s["success"] and rep["plan"]["window_s"] == 10 and len(rep["plan"]["windows"]) >= 5
    for who in "AB":
        m = load_bvh(out / f"{who}.bvh")
        assert abs(m.num_frames - MIXED_S * m.fps) <= 1.0
    by_kind = [ch["checker"]["total"]["by_kind"] for ch in rep["characters"].values()]
    met = sum(k["met"] for b in by_kind for k in b.values())
    total = sum(k["total"] for b in by_kind for k in b.values())
    pc_met, pc = sum(b["PC"]["met"] for b in by_kind), sum(b["PC"]["total"] for b in by_kind)
    assert pc >= 6 and met >= 0.9 * total and pc_met >= 0.85 * pc, by_kind


def _constraints(rep, who):
    return rep["characters"][who]["checker"]["total"]["constraints"]


def test_a_clause_across_a_cut_is_met(mixed):
    _, _, rep = mixed
    across = []
    for who, ch in rep["characters"].items():
        cuts = [w["start"] for w in ch["windows"][1:]]
        across += [c for c in _constraints(rep, who) if c["kind"] != "idle"
                   and any(c["start"] < t < c["end"] for t in cuts)]
    assert across, "the input has no clause across a cut: the test does not test it"
    assert all(c["met"] for c in across), across


def test_a_long_silence_and_overlapping_speech_are_met(mixed):
    _, _, rep = mixed
    fps = rep["inputs"]["fps"]
    for who in "AB":
        silent = [c for c in _constraints(rep, who) if c["kind"] == "idle" and c["start"] <= 24 * fps and c["end"] >= 37 * fps]
        assert len(silent) == 1 and silent[0]["met"], _constraints(rep, who)
        overlap = [c for c in _constraints(rep, who) if c["kind"] != "idle" and c["start"] < 14 * fps and c["end"] > 11 * fps]
        assert overlap and all(c["met"] for c in overlap), overlap


def test_paper_preset_fails_naming_the_constraint_and_what_makes_motion(mixed, tiny_corpus_dir, cache, tmp_path):
    """preset=paper keeps the paper's strict rule: on the same hard input a window has no path, and the
    failure names the constraint, its output frames and preset=quality."""
    d = mixed[0].parent
    ins = {f"{k}_{x}": d / f"{x}.{ext}" for x in "ab" for k, ext in (("audio", "wav"), ("transcript", "tsv"))}
    with pytest.raises(SearchFailure, match=r"(?s)window \d+ .*constraint at output frames \d+-\d+.*preset=quality"):
        run_task(converse_cfg(tiny_corpus_dir, cache, ins, "task.video=false", "preset=paper"), tmp_path)
    assert not json.loads((tmp_path / "report.json").read_text())["success"]


# ---------------------------------------------------------------------------------------------- speech as users have it
def test_a_channel_per_speaker_and_a_log_line_for_dropped_channels(inputs, tmp_path, caplog):
    """A stereo WAV given as task.audio_a used to lose channel 1 without a word: now a warning names the
    dropped channel and the key choosing another; task.channel_a picks it; a channel out of range is an
    error naming the file and the key."""
    from convsynth_jax.io import load_audio, save_wav
    from convsynth_jax.tasks.converse import ConverseParams, load_inputs

    a, b = load_audio(inputs["audio_a"]), load_audio(inputs["audio_b"])
    save_wav(tmp_path / "ab.wav", np.stack([a.samples, b.samples], axis=1), a.sample_rate)
    given = dict(audio_a=str(tmp_path / "ab.wav"), transcript_a=str(inputs["transcript_a"]))
    with caplog.at_level("WARNING"):
        A, _, _ = load_inputs(ConverseParams(**given))
    assert "ab.wav has 2 channels; channel 0 is used, channel(s) [1] dropped (set task.channel_a" in caplog.text
    np.testing.assert_allclose(A.audio.samples, a.samples, atol=1e-4)
    A1, _, _ = load_inputs(ConverseParams(**given, channel_a=1))
    np.testing.assert_allclose(A1.audio.samples, b.samples, atol=1e-4)
    with pytest.raises(AudioFormatError, match=r"ab\.wav: channel 2 requested for speaker B \(task\.channel_b\).*"
                                               r"set task\.channel_b to one of 0\.\.1"):
        load_inputs(ConverseParams(stereo=str(tmp_path / "ab.wav"), transcript_a=given["transcript_a"],
                                   transcript_b=str(inputs["transcript_b"]), channel_b=2))


def test_a_tier_per_speaker_and_phrase_tiers_aligned(tmp_path, caplog):
    """One TextGrid with a sentence-level tier per speaker (a label broken over two lines): task.tier_a /
    task.tier_b pick each speaker's tier, the sentences are aligned to the audio into words (with a log
    line); a tier that does not exist names the key to set."""
    from conftest import TEST_DATA
    from convsynth_jax.io import load_audio, load_transcript, save_wav
    from convsynth_jax.io.transcripts import textgrid_text
    from convsynth_jax.tasks.converse import ConverseParams, load_inputs

    a, ref = load_audio(TEST_DATA / "speech_clip.wav"), load_transcript(TEST_DATA / "speech_clip.tsv")
    save_wav(tmp_path / "ab.wav", np.stack([a.samples, a.samples[::-1]], axis=1), a.sample_rate)
    sent = pd.DataFrame([(0.55, 1.99, "this is the\nacoustic corpus"), (1.99, 4.81, ref["word"][5:].str.cat(sep=" "))],
                        columns=["start", "end", "word"])
    one = pd.DataFrame([(0.1, 0.4, "oh")], columns=["start", "end", "word"])
    text = textgrid_text(sent, a.duration, "ann")
    other = textgrid_text(one, a.duration, "bob").split("item [1]:", 1)[1]
    text = text.replace("size = 1\n", "size = 2\n", 1) + "    item [2]:" + other
    (tmp_path / "two.TextGrid").write_text(text)
    p = dict(stereo=str(tmp_path / "ab.wav"), transcript_a=str(tmp_path / "two.TextGrid"),
             transcript_b=str(tmp_path / "two.TextGrid"), tier_a="ann", tier_b="bob")
    with caplog.at_level("INFO"):
        A, B, _ = load_inputs(ConverseParams(**p))
    assert "speaker A: 2 of the 2 rows of" in caplog.text and "aligned to the audio" in caplog.text
    assert A.words_source == "aligned" and [w.lower() for w in A.words["word"]] == ref["word"].tolist()
    assert np.mean(np.abs(A.words["start"].to_numpy() - ref["start"].to_numpy()) < 0.05) >= 0.85
    assert B.words_source == "transcript" and B.words["word"].tolist() == ["oh"]
    with pytest.raises(TranscriptFormatError, match=r"two\.TextGrid: no tier named 'B'.*\['ann', 'bob'\].*set task\.tier_b"):
        load_inputs(ConverseParams(**{**p, "tier_b": "B"}))


def test_no_transcript_recognizes_words_and_writes_them_to_correct(tiny_corpus_dir, cache, tmp_path, caplog):
    """Audio without a transcript: the words are recognized offline (logged as such), written to
    words_A.tsv, and that file passed back as the transcript gives the same conversation. Audio where
    nothing is recognized is an error naming the file and the key, and nothing is written."""
    from conftest import TEST_DATA
    from convsynth_jax.io import load_transcript, save_wav

    clip = {"audio_a": TEST_DATA / "speech_clip.wav"}
    with caplog.at_level("INFO"):
        s = run_task(converse_cfg(tiny_corpus_dir, cache, clip, "task.video=false"), tmp_path / "rec")
    assert "no transcript (task.transcript_a)" in caplog.text and "offline recognizer" in caplog.text
    words = load_transcript(tmp_path / "rec" / "words_A.tsv")
    assert len(words) >= 8 and "acoustic" in words["word"].tolist()
    assert s["speakers"]["A"]["words"] == {"source": "recognized", "count": len(words), "transcript": "(recognized)"}
    caplog.clear()
    with caplog.at_level("INFO"):
        back = run_task(converse_cfg(tiny_corpus_dir, cache, {**clip, "transcript_a": tmp_path / "rec" / "words_A.tsv"},
                                     "task.video=false", "task.progress_s=0.01"), tmp_path / "back")
    assert back["speakers"]["A"]["words"]["source"] == "transcript"
    assert "searching: " in caplog.text                   # progress while the searches run
    assert (tmp_path / "back" / "A.bvh").read_text() == (tmp_path / "rec" / "A.bvh").read_text()
    save_wav(tmp_path / "quiet.wav", np.zeros(48000), 16000)
    with pytest.raises(TranscriptFormatError, match=r"quiet\.wav: no words recognized in speaker A's audio.*"
                                                    r"task\.transcript_a=FILE"):
        run_task(converse_cfg(tiny_corpus_dir, cache, {"audio_a": tmp_path / "quiet.wav"}), tmp_path / "quiet")
    assert not any((tmp_path / "quiet").iterdir())


def test_summary_says_what_was_met_and_what_best_effort_dropped(chained):
    """success means motion was written; all_constraints_met whether every constraint was met; per
    speaker the checker's counts by kind, best effort's drops and the missed constraints."""
    from convsynth_jax.tasks.converse import speaker_line, speaker_summary

    out, s = chained
    rep = json.loads((out / "report.json").read_text())
    for w in "AB":
        sp = s["speakers"][w]
        tot = rep["characters"][w]["checker"]["total"]
        assert sp["constraints"]["met"] == tot["met"] and sp["constraints"]["total"] == tot["total"]
        assert sum(k["total"] for k in sp["constraints"]["by_kind"].values()) == tot["total"]
        assert len(sp["missed"]) == tot["total"] - tot["met"]
    assert s["success"] is True
    assert s["all_constraints_met"] == all(s["constraints_met"][w] == s["constraints_total"][w] for w in "AB")
    # a best-effort window that dropped two constraints and a checker that finds one missed
    rep["characters"]["A"]["windows"][0].update(status="best_effort", relaxed=[["PC", 3, 40], ["idle", 50, 90]])
    tot = rep["characters"]["A"]["checker"]["total"]
    tot["missed"] = [{"kind": "PC", "start": 30, "end": 45, "met": False}]
    tot["met"] = tot["total"] - 1
    sp = speaker_summary(rep, "A", 30.0)
    assert sp["best_effort"] == {"windows": [0], "dropped": 2, "dropped_by_kind": {"PC": 1, "idle": 1}}
    assert sp["missed"] == [{"kind": "PC", "start_s": 1.0, "end_s": 1.5}]
    line = speaker_line("A", sp)
    assert f"constraints met {tot['met']}/{tot['total']}" in line and "best effort in window(s) [0] dropped 2 (PC 1, idle 1)" \
        in line and "missed: PC 1.00-1.50 s" in line


def test_writing_the_video_runs_no_fork_hook(tmp_path):
    """The video's ffmpeg used to start through a preexec_fn, which runs the at-fork hooks: JAX's warns
    'os.fork() was called ... deadlock' on every run. Now no hook runs."""
    import os

    from convsynth_jax.render import write_mp4

    forks = []
    os.register_at_fork(before=lambda: forks.append(1))
    frames = np.zeros((3, 16, 16, 3), np.uint8)
    write_mp4(tmp_path / "v.mp4", frames[0], iter(frames[1:]), 5.0)
    assert (tmp_path / "v.mp4").stat().st_size > 0 and forks == []


def test_progress_bars_only_on_a_terminal():
    import io

    from convsynth_jax.utils import show_progress_bar

    class Tty(io.StringIO):
        def isatty(self):
            return True

    assert show_progress_bar(True, Tty()) and not show_progress_bar(False, Tty())
    assert not show_progress_bar(True, io.StringIO())          # a file or a pipe: no bar, no escape codes
