import filecmp
import json

import numpy as np
import pandas as pd
import pytest
from scipy import stats

from convsynth_jax.annotate.kinds import hypotheses
from convsynth_jax.data import ensure_synthetic_corpus, make_synthetic_corpus, resolve_config
from convsynth_jax.errors import ConfigError
from convsynth_jax.io import load_bvh, load_corpus
from conftest import _build_once
from tolerances import F0_RELATIVE

SMALL = {"num_sessions": 2, "session_seconds": 20.0}
MOTION_ONLY = {"num_sessions": 8, "session_seconds": 120.0, "write_audio": False}
# every difficulty knob off (the easy corpus of generator version 2, as conf/corpus/synthetic_tiny.yaml)
EASY = {"p_clause_pause": 1.0, "final_lengthening": 1.0, "p_backchannel_overlap": 0.0, "p_turn_overlap": 0.0,
        "coarticulation_gap": 0.0, "sensor_noise_deg": 0.03, "sensor_noise_cm": 0.0, "glitches_per_minute": 0.0,
        "posture_shift_sd": 0.0, "calibrate_rates": False, "quota_planting": False}


@pytest.fixture(scope="session")
def motion_corpus(_shared_dir):
    """A moderately sized corpus without audio (several seconds to write, once per test run, shared by
    the pytest-xdist workers; read it, never write into it): rates and kinematics."""
    return _build_once(_shared_dir, "synthetic_motion_corpus", lambda out: make_synthetic_corpus(out / "c", MOTION_ONLY)) / "c"


def test_same_seed_same_bytes_other_seed_differs(tmp_path):
    a = make_synthetic_corpus(tmp_path / "a", SMALL)
    b = make_synthetic_corpus(tmp_path / "b", SMALL)
    c = make_synthetic_corpus(tmp_path / "c", {**SMALL, "seed": 1})
    names = sorted(p.name for p in a.iterdir())
    assert names == sorted(p.name for p in b.iterdir()) and len(names) == 2 * 6 + 3  # + glitches.csv
    match, mismatch, errors = filecmp.cmpfiles(a, b, names, shallow=False)
    assert mismatch == [] and errors == []
    assert not filecmp.cmp(a / "session01_main-agent.bvh", c / "session01_main-agent.bvh", shallow=False)


def test_written_corpus_loads(tmp_path):
    root = make_synthetic_corpus(tmp_path / "c", SMALL)
    corpus = load_corpus(root)
    assert corpus.characters == ["female", "male"]
    m = corpus.sessions[0].participants[0].load_motion()
    assert 25 <= m.skeleton.num_joints <= 35 and m.fps == 30
    assert abs(m.root_positions[:, 1].mean() - 48) < 3  # the root stays near the chair
    ev = pd.read_csv(root / "events.csv")
    assert set(ev["kind"]) <= {"PC", "LR", "HP", "LH", "RH", "Nod"}
    assert {"session", "participant", "kind", "start", "peak", "end"} <= set(ev.columns)


def test_invalid_probabilities_rejected():
    with pytest.raises(ConfigError):
        resolve_config({"characters": {"main-agent": {"p_pc_either": 0.3}}})


@pytest.fixture(scope="session")
def easy_corpus(_shared_dir):
    """The same size without the difficulty knobs (independent Bernoulli planting); shared as above."""
    return _build_once(_shared_dir, "synthetic_easy_corpus",
                       lambda out: make_synthetic_corpus(out / "e", {**MOTION_ONLY, **EASY})) / "e"


def test_tiny_config_is_the_easy_corpus():
    from convsynth_jax.config import compose

    gen = compose(["corpus=synthetic_tiny"]).corpus.generator
    assert {k: gen[k] for k in EASY} == EASY


def test_unknown_generator_key_rejected():
    with pytest.raises(ConfigError, match="posture_shift_Sd"):
        resolve_config({"posture_shift_Sd": 3.0})


def test_planted_rates_match_configuration(easy_corpus):
    """With independent planting (quota and calibration off), planted gesture/nod rates agree with
    the configured probabilities: a two-sided binomial test must not reject at the 0.1% level."""
    ev = pd.read_csv(easy_corpus / "events.csv")
    cfg = resolve_config({})
    for role, ch in cfg["characters"].items():
        own = ev[ev["participant"] == role]
        src = own[own["kind"].isin(["LH", "RH", "Nod"])]
        n_pc = int((own["kind"] == "PC").sum())
        for kind, p in (("LH", ch["p_pc_lh"]), ("RH", ch["p_pc_rh"])):
            k = int(((src["kind"] == kind) & (src["source"] == "PC")).sum())
            assert stats.binomtest(k, n_pc, p).pvalue > 1e-3, (role, kind, k, n_pc, p)
        pc_gest = src[src["source"] == "PC"]
        either = pc_gest.groupby(["session", "cause_start"]).ngroups  # clauses with at least one gesture
        assert stats.binomtest(either, n_pc, ch["p_pc_either"]).pvalue > 1e-3
        n_lr = int((own["kind"] == "LR").sum())
        k = int(((src["kind"] == "Nod") & (src["source"] == "LR")).sum())
        assert stats.binomtest(k, n_lr, ch["p_lr_nod"]).pvalue > 1e-3
        partner = ev[(ev["participant"] != role) & (ev["kind"] == "HP")]
        k = int(((src["kind"] == "Nod") & (src["source"] == "HP")).sum())
        assert stats.binomtest(k, len(partner), ch["p_ph_nod"]).pvalue > 1e-3


def test_praat_recovers_planted_f0_and_words_are_voiced():
    import parselmouth

    from convsynth_jax.data.synthetic import _conversation, _render_voice

    cfg = resolve_config({})
    rng = np.random.default_rng(5)
    segs = _conversation(rng, cfg, 20.0, 1.0)
    for role, f0b in (("main-agent", 210.0), ("interloctr", 118.0)):
        own = [s for s in segs if s.role == role]
        sig, f0 = _render_voice(own, f0b, 20.0, 16000, rng, cfg["accent_rise"])
        pitch = parselmouth.Sound(sig, 16000).to_pitch(time_step=0.01, pitch_floor=75, pitch_ceiling=500)
        t, f = pitch.xs(), pitch.selected_array["frequency"]
        planted = f0[np.clip((t * 16000).astype(int), 0, len(f0) - 1)]
        both = (f > 0) & (planted > 0)
        assert both.sum() > 100
        rel = np.abs(f[both] - planted[both]) / planted[both]
        assert np.mean(rel < F0_RELATIVE) > 0.98
        # transcript words lie where the signal is voiced
        words = [w for s in own for w in s.words]
        mids = np.array([(w[0] + w[1]) / 2 for w in words])
        idx = np.clip(np.searchsorted(t, mids), 0, len(t) - 1)
        assert np.mean(f[idx] > 0) > 0.9


def _union_length(intervals, lo, hi):
    """Length of the union of ``intervals`` clipped to [lo, hi], on a 1 ms grid (independent of the
    generator's interval code)."""
    grid = np.zeros(int(round((hi - lo) * 1000)), bool)
    for a, b in intervals:
        i, j = int(np.clip(round((a - lo) * 1000), 0, grid.size)), int(np.clip(round((b - lo) * 1000), 0, grid.size))
        grid[i:j] = True
    return grid.sum() / 1000.0


def test_spontaneous_movements_away_from_windows_at_configured_rate(motion_corpus):
    """Spontaneous gestures and nods lie outside the participant's own candidate windows (twice the
    segment length around it) and its partner's hesitation windows, keep 0.3 s from its other
    events, and their number matches rate x available time (Poisson test)."""
    ev = pd.read_csv(motion_corpus / "events.csv")
    meta = json.loads((motion_corpus / "corpus.json").read_text())
    cfg = resolve_config({})
    total_free, total_n = 0.0, 0
    for sess in meta["sessions"]:
        for role in ("main-agent", "interloctr"):
            e = ev[ev.session == sess["name"]]
            audio = e[e.kind.isin(["PC", "LR", "HP"]) & ((e.participant == role) | (e.kind == "HP"))]
            win = [(r.start - (r.end - r.start) / 2, r.end + (r.end - r.start) / 2) for r in audio.itertuples()]
            motion = e[(e.participant == role) & e.kind.isin(["LH", "RH", "Nod"])]
            sp, caused = motion[motion.source == "spontaneous"], motion[motion.source != "spontaneous"]
            for r in sp.itertuples():
                assert all(r.end <= a or r.start >= b for a, b in win), (sess["name"], role, r)
                assert all(r.end + 0.3 <= c.start or r.start >= c.end + 0.3 for c in caused.itertuples())
            busy = win + [(c.start - 0.4, c.end + 0.4) for c in caused.itertuples()]
            dur = sess["duration"]
            free = (dur - 2.5) - _union_length(busy, 1.0, dur - 1.5)
            assert abs(free - sess["spontaneous_free_seconds"][role]) < 0.05
            total_free += free
            total_n += len(sp)
    expected = cfg["spontaneous_per_minute"] * total_free / 60.0
    assert total_n > 0
    assert stats.poisson.cdf(total_n, expected) > 5e-4 and stats.poisson.sf(total_n - 1, expected) > 5e-4


def test_same_channel_events_keep_idle_between(motion_corpus, easy_corpus):
    """Consecutive events of the head, and of the same hand unless coarticulated, leave at least
    min_event_gap of idle, so a threshold segmenter can find both edges; coarticulated hand gestures
    abut exactly (one ends where the next starts). The easy corpus has no coarticulation."""
    gap = resolve_config({})["min_event_gap"]
    for root, coartic in ((motion_corpus, True), (easy_corpus, False)):
        ev = pd.read_csv(root / "events.csv")
        for (_, _, kind), g in ev[ev.kind.isin(["LH", "RH", "Nod"])].groupby(["session", "participant", "kind"]):
            g = g.sort_values("start")
            d = g.start.values[1:] - g.end.values[:-1]
            abut = np.abs(d) < 1e-3
            if kind == "Nod" or not coartic:
                assert not abut.any(), kind
            assert (abut | (d >= gap - 1e-3)).all(), kind
            assert ((g.start < g.peak) & (g.peak < g.end)).all()


def _hand_offsets(m):
    """(F, 2, 3) left/right hand position relative to Spine2, in the hips' heading frame (cm)."""
    from convsynth_jax.kinematics import global_transforms

    pos = np.asarray(global_transforms(m)[0], np.float64)
    names = list(m.skeleton.names)
    return np.stack([pos[:, names.index(f"{s}Hand")] - pos[:, names.index("Spine2")] for s in ("Left", "Right")], 1)


def test_gestures_run_into_each_other(motion_corpus):
    """Gesture adjacency: a good share of consecutive same-hand gestures are coarticulated (no idle
    between them), and at their shared boundary the hand is held away from where it rested before
    the first of them, while between separate gestures it comes back close to that rest."""
    ev = pd.read_csv(motion_corpus / "events.csv")
    hands = ev[ev.kind.isin(["LH", "RH"])]
    pairs = abut = 0
    held, returned = [], []
    for (s, role, kind), g in hands.groupby(["session", "participant", "kind"]):
        g = g.sort_values("start")
        d = g.start.values[1:] - g.end.values[:-1]
        pairs += d.size
        abut += int((np.abs(d) < 1e-3).sum())
        if s not in ("session01", "session02"):
            continue
        m = load_bvh(motion_corpus / f"{s}_{role}.bvh")
        h = _hand_offsets(m)[:, 0 if kind == "LH" else 1]
        frame = lambda x: int(np.clip(round(x * m.fps), 0, m.num_frames - 1))  # noqa: E731
        for i in range(d.size):
            rest = h[frame(g.start.values[i] - 0.05)]
            if abs(d[i]) < 1e-3:
                held.append(np.linalg.norm(h[frame(g.end.values[i])] - rest))
            elif d[i] > 0.5:
                returned.append(np.linalg.norm(h[frame(g.end.values[i] + d[i] / 2)] - rest))
    assert pairs > 200 and 0.1 < abut / pairs < 0.6, (abut, pairs)
    assert len(held) >= 10 and len(returned) >= 10
    assert np.median(held) > 2 * np.median(returned), (np.median(held), np.median(returned))


def test_easy_corpus_has_no_coarticulation(easy_corpus):
    ev = pd.read_csv(easy_corpus / "events.csv")
    for _, g in ev[ev.kind.isin(["LH", "RH"])].groupby(["session", "participant", "kind"]):
        g = g.sort_values("start")
        assert (g.start.values[1:] - g.end.values[:-1] > 0.2).all()


def _stretches(tsv, pause=0.2):
    """Words per pause-free stretch (a pause: ``pause`` s or more between consecutive words) of one transcript."""
    w = pd.read_csv(tsv, sep="\t", header=None, names=["start", "end", "word"])
    brk = np.flatnonzero(w.start.values[1:] - w.end.values[:-1] >= pause)
    return np.diff(np.concatenate([[0], brk + 1, [len(w)]]))


def test_fluent_speech_and_overlapping_speech(motion_corpus, easy_corpus):
    """Fluent stretches: most clause boundaries inside a turn have no pause, so pause-free stretches
    hold many words; overlap: backchannels over the partner's clauses and turns that start before
    the other speaker has finished. The easy corpus has neither: every clause ends in a pause (at
    least the shortest clause pause at the fastest speech rate), so no stretch outgrows a clause."""
    from convsynth_jax.data.synthetic import EMOTIONS

    cfg = resolve_config({})
    shortest = cfg["clause_pause"][0] / max(rate for _, rate in EMOTIONS.values())
    assert shortest > cfg["word_gap"][1]

    def measure(root, pause=0.2):
        ev = pd.read_csv(root / "events.csv")
        words = np.concatenate([_stretches(p, pause) for p in sorted(root.glob("*.tsv"))])
        pc, lr = ev[ev.kind == "PC"], ev[ev.kind == "LR"]
        lr_over = np.mean([((pc.session == r.session) & (pc.participant != r.participant) & (pc.start < r.end)
                            & (pc.end > r.start)).any() for r in lr.itertuples()])
        turn_over = sum(((pc.session == r.session) & (pc.participant != r.participant) & (pc.start < r.start)
                         & (pc.end > r.start)).any() for r in pc.itertuples())
        own = ev[ev.kind.isin(["PC", "LR", "HP"])].sort_values(["session", "participant", "start"])
        for _, g in own.groupby(["session", "participant"]):  # one participant never overlaps itself
            assert (g.start.values[1:] >= g.end.values[:-1] + 0.02).all()
        return words, lr_over, turn_over / len(pc)

    words, lr_over, turn_over = measure(motion_corpus)
    assert np.percentile(words, 90) >= 8 and words.max() >= 15, np.percentile(words, [50, 90, 100])
    assert lr_over > 0.3 and turn_over > 0.02, (lr_over, turn_over)
    words, lr_over, turn_over = measure(easy_corpus, shortest - 1e-3)
    assert words.max() <= cfg["max_clause_words"] and lr_over == 0 and turn_over == 0


def test_sensor_noise_level(tmp_path):
    """The leg joints carry nothing but measurement noise: the spread of their rotation channels is
    the configured ``sensor_noise_deg`` (white: successive differences have sqrt(2) times that)."""
    for sd in (0.12, 0.5):
        root = make_synthetic_corpus(tmp_path / f"n{sd}", {"num_sessions": 1, "session_seconds": 30.0,
                                                            "write_audio": False, "sensor_noise_deg": sd})
        m = load_bvh(root / "session01_main-agent.bvh")
        from convsynth_jax.rotations import quat_to_euler_deg_np

        j = list(m.skeleton.names).index("LeftLeg")
        e = quat_to_euler_deg_np(np.asarray(m.rotations[:, j], np.float64), "ZXY")
        measured = np.diff(e, axis=0).std(0) / np.sqrt(2)
        np.testing.assert_allclose(measured, sd, rtol=0.1)


def test_glitches_listed_visible_and_at_the_configured_rate(motion_corpus):
    """glitches.csv lists the marker-swap glitches: their number fits the configured rate (Poisson
    test over 8 sessions x 2 participants x 2 minutes), each is a jump of its joint's rotation at its
    first frame and back after its last, far above frame-to-frame motion elsewhere."""
    gl = pd.read_csv(motion_corpus / "glitches.csv")
    cfg = resolve_config({})
    expected = cfg["glitches_per_minute"] * 8 * 2 * 2.0
    assert stats.poisson.cdf(len(gl), expected) > 1e-3 and stats.poisson.sf(len(gl) - 1, expected) > 1e-3
    assert set(gl.kind) == {"flip", "jump"}
    lo, hi = cfg["glitch_frames"]
    assert ((gl.end_frame - gl.start_frame).between(lo, hi)).all()
    for (s, role), g in gl.groupby(["session", "participant"]):
        m = load_bvh(motion_corpus / f"{s}_{role}.bvh")
        q = np.asarray(m.rotations, np.float64)
        step = 2 * np.degrees(np.arccos(np.clip(np.abs(np.sum(q[1:] * q[:-1], -1)), 0, 1)))  # (F-1, J)
        names = list(m.skeleton.names)
        glitched = np.zeros_like(step, bool)
        for r in g.itertuples():
            j = names.index(r.joint)
            assert step[r.start_frame - 1, j] > 10 and step[r.end_frame - 1, j] > 10, r
            glitched[r.start_frame - 1: r.end_frame, j] = True
        assert np.percentile(step[~glitched], 99.9) < 8


def test_no_glitches_when_off(easy_corpus):
    assert len(pd.read_csv(easy_corpus / "glitches.csv")) == 0


def _reference_window_rate(ev, role, akind, kinds, whose):
    """Share of the hypothesis' audio segments whose window (twice the segment around its centre,
    trimmed to the channel's neighbouring segments, starting no earlier than the end of the movement
    matched by the previous window) overlaps a movement of the kinds: plain loops,
    independent of the generator's window_matches."""
    hits = n = 0
    for s in sorted(ev.session.unique()):
        e = ev[ev.session == s]
        owner = role if whose == "own" else ("interloctr" if role == "main-agent" else "main-agent")
        chan = e[(e.participant == owner) & e.kind.isin(["PC", "LR", "HP"])].sort_values("start")
        mv = e[(e.participant == role) & e.kind.isin(kinds)]
        last_end = -1e9
        rows = list(chan.itertuples())
        for i, r in enumerate(rows):
            if r.kind != akind:
                continue
            n += 1
            lo, hi = r.start - (r.end - r.start) / 2, r.end + (r.end - r.start) / 2
            for o in rows:
                if o.end <= r.start and o.start < r.start:
                    lo = max(lo, o.end)
                if o.start >= r.end and o.end > r.end:
                    hi = min(hi, o.start)
            lo = max(lo, last_end)
            ends = [x.end for x in mv.itertuples() if x.start < hi and x.end > lo]
            if hi > lo and ends:
                hits += 1
                last_end = max(ends)
    return hits / n, n


# hypothesis -> (audio kind, motion kinds, channel, planting key): the registry's table
HYPS = {h.name: (h.label, list(h.motions), h.channel, h.planting) for h in hypotheses()}


def _detector_rates(root):
    """{(role, hypothesis): (rate, n)} as the annotation pipeline counts the written corpus: each BVH
    read back, its joint speeds and Eq. 1 recording thresholds, ``hypothesis_matches`` over the
    planted audio segments of events.csv."""
    from convsynth_jax.annotate.motion import joint_speeds, recording_thresholds
    from convsynth_jax.annotate.params import AnnotateParams
    from convsynth_jax.stats.cooccurrence import hypothesis_matches

    ev = pd.read_csv(root / "events.csv")
    counts = {}
    for s, e in ev.groupby("session"):
        segs = {r: e[(e.participant == r) & e.kind.isin(["PC", "LR", "HP"])].sort_values("start") for r in ROLES}
        for k, role in enumerate(ROLES):
            m = load_bvh(root / f"{s}_{role}.bvh")
            sp = joint_speeds(m, AnnotateParams())
            thr = recording_thresholds(sp)
            for h in HYPS:
                hit, _ = hypothesis_matches(sp, segs[role], segs[ROLES[1 - k]], m.fps, h, thresholds=thr)
                c = counts.setdefault((role, h), [0, 0])
                c[0] += int(hit.sum())
                c[1] += hit.size
    return {key: (hit / n, n) for key, (hit, n) in counts.items()}


ROLES = ("main-agent", "interloctr")


def test_detected_rates_match_configured(motion_corpus):
    """Calibration against the detector: on a 16-minute hard corpus (8 x 120 s; about
    230 clauses, 100 responses and 45 partner hesitations per character) the co-occurrence rates as
    the annotation pipeline's detector and counter measure them on the written files lie within 2
    percentage points of the configured Table 1 rates (or 1.5 segments for the smaller rows: the
    quotas are whole segments). Calibrated against the interval emulation (generator version 3),
    the hand rows came out 5-11 points above."""
    cfg = resolve_config({})
    rates = _detector_rates(motion_corpus)
    for role, ch in cfg["characters"].items():
        for h, (_, _, _, key) in HYPS.items():
            rate, n = rates[(role, h)]
            assert n >= 30
            assert abs(rate - ch[key]) <= max(0.02, 1.5 / n) + 1e-9, (role, h, rate, ch[key], n)


def test_calibration_report_is_what_the_files_measure(motion_corpus):
    """The chosen calibration pass counted the motion it rendered in memory; the files written from
    that plan measure the same rates (up to one segment: BVH stores 4 decimals)."""
    report = json.loads((motion_corpus / "corpus.json").read_text())["calibration"]
    assert report["measure"] == "detector"
    rows = report["passes"][report["chosen_pass"]]["rows"]
    for (role, h), (rate, n) in _detector_rates(motion_corpus).items():
        assert abs(rows[f"{role} {h}"]["realized"] - rate) <= 1.0 / n + 1e-4, (role, h)


def test_calibrate_against_windows_still_matches_window_rates(tmp_path):
    """The old measure stays available (``calibrate_against: windows``): the realized rates as
    window_matches sees the planted intervals then lie near the configured ones (a 4 x 120 s corpus;
    3 points or 2 segments)."""
    root = make_synthetic_corpus(tmp_path / "w", {**MOTION_ONLY, "num_sessions": 4, "calibrate_against": "windows",
                                                  "calibration_passes": 8})
    assert json.loads((root / "corpus.json").read_text())["calibration"]["measure"] == "windows"
    ev = pd.read_csv(root / "events.csv")
    for role, ch in resolve_config({})["characters"].items():
        for h, (akind, kinds, whose, key) in HYPS.items():
            rate, n = _reference_window_rate(ev, role, akind, kinds, whose)
            assert abs(rate - ch[key]) <= max(0.03, 2.0 / n) + 1e-9, (role, h, rate, ch[key], n)


def test_unknown_calibration_measure_rejected():
    with pytest.raises(ConfigError, match="calibrate_against: .detectr.; expected one of"):
        resolve_config({"calibrate_against": "detectr"})


def test_every_accepted_calibration_measure_exists():
    """The names the configuration accepts (config.CALIBRATION_MEASURES) are the measures the
    calibration has (calibration.CALIBRATION_MEASURES), so no accepted name fails later."""
    from convsynth_jax.data.synthetic import calibration, config

    assert tuple(calibration.CALIBRATION_MEASURES) == config.CALIBRATION_MEASURES


def test_motion_does_not_depend_on_audio_rendering(tmp_path):
    """The calibration renders motion without audio and must get the motion that is written with
    audio: each participant's motion draws from a stream of its own (before, the audio of the first
    participant consumed the generator the second one's motion drew from)."""
    a = make_synthetic_corpus(tmp_path / "a", {**SMALL, "calibrate_rates": False})
    b = make_synthetic_corpus(tmp_path / "b", {**SMALL, "calibrate_rates": False, "write_audio": False})
    bvh = sorted(p.name for p in a.iterdir() if p.suffix == ".bvh")
    assert len(bvh) == 4
    match, mismatch, errors = filecmp.cmpfiles(a, b, bvh, shallow=False)
    assert mismatch == [] and errors == []


def test_planting_is_nested_in_the_probabilities():
    """Planting with a higher p_pc_lh (and p_pc_either) adds left-hand gestures: the clauses that
    cause one at p are a subset of those at p + 0.1. The right hand keeps its count (up to the
    quota's rounding), and its clauses move by at most as many as the left hand gained (the quota's
    category intervals shift); which segments cause nods stays as it was, and the other
    participant's movements too.
    The calibration's fixed point relies on nearby p giving nearby corpora; before, every draw after
    the first changed count was a different one."""
    from convsynth_jax.data.synthetic import HYPOTHESIS_KEYS, _plan, _quota_offsets

    # 150 s: sessions of about 30-45 main-agent clauses (the clauses of generator version 5 are longer)
    cfg = resolve_config({**MOTION_ONLY, "num_sessions": 2, "session_seconds": 150.0})
    base = {r: {v[3]: cfg["characters"][r][v[3]] for v in HYPOTHESIS_KEYS.values()} for r in ROLES}
    more = {r: dict(v) for r, v in base.items()}
    more["main-agent"]["p_pc_lh"] += 0.1
    more["main-agent"]["p_pc_either"] += 0.1
    off = _quota_offsets(cfg)
    for i in range(2):
        lo, hi = _plan(i, cfg, base, off)["events"], _plan(i, cfg, more, off)["events"]

        def causes(evs, kind, source):
            return {round(e["cause_start"], 6) for e in evs if e["kind"] == kind and e["source"] == source}

        a, b = causes(lo["main-agent"], "LH", "PC"), causes(hi["main-agent"], "LH", "PC")
        assert a < b and len(b) - len(a) >= 3
        ra, rb = causes(lo["main-agent"], "RH", "PC"), causes(hi["main-agent"], "RH", "PC")
        assert abs(len(ra) - len(rb)) <= 2 and len(ra ^ rb) <= 2 * (len(b) - len(a)) + 2, (len(ra ^ rb), len(b - a))
        for kind, source in (("Nod", "LR"), ("Nod", "HP")):
            assert causes(lo["main-agent"], kind, source) == causes(hi["main-agent"], kind, source)
        assert lo["interloctr"] == hi["interloctr"]


def test_fast_euler_conversion_matches_scipy():
    from convsynth_jax.data.synthetic import _zxy_deg_to_quat
    from convsynth_jax.rotations import euler_deg_to_quat_np

    e = np.random.default_rng(0).uniform(-200, 200, (500, 3))
    a, b = _zxy_deg_to_quat(e), euler_deg_to_quat_np(e, "ZXY")
    np.testing.assert_allclose(np.abs(np.sum(a * b, axis=-1)), 1.0, atol=1e-12)  # same rotation (q ~ -q)
    np.testing.assert_allclose(np.linalg.norm(a, axis=-1), 1.0, atol=1e-12)


def test_window_matches_agrees_with_reference(motion_corpus):
    from convsynth_jax.data.synthetic import window_matches

    ev = pd.read_csv(motion_corpus / "events.csv")
    for role in ("main-agent", "interloctr"):
        for akind, kinds, whose, _ in HYPS.values():
            ref, n = _reference_window_rate(ev, role, akind, kinds, whose)
            hits = 0
            for s in sorted(ev.session.unique()):
                e = ev[ev.session == s]
                owner = role if whose == "own" else ("interloctr" if role == "main-agent" else "main-agent")
                chan = e[(e.participant == owner) & e.kind.isin(["PC", "LR", "HP"])]
                mv = e[(e.participant == role) & e.kind.isin(kinds)]
                hits += window_matches(chan[chan.kind == akind][["start", "end"]].values, chan[["start", "end"]].values,
                                       mv[["start", "end"]].values).sum()
            assert hits == round(ref * n)


def test_quota_planting_hits_the_causal_counts(tmp_path):
    """Quota planting without calibration: per session, the number of clauses with a planted left-hand
    gesture is floor(p n + u) or its neighbour; summed over sessions within 1.5 points of p."""
    root = make_synthetic_corpus(tmp_path / "q", {**MOTION_ONLY, "calibrate_rates": False})
    ev = pd.read_csv(root / "events.csv")
    cfg = resolve_config({})
    for role, ch in cfg["characters"].items():
        own = ev[ev.participant == role]
        n = int((own.kind == "PC").sum())
        k = int(((own.kind == "LH") & (own.source == "PC")).sum())
        either = own[own.source == "PC"].groupby(["session", "cause_start"]).ngroups
        assert abs(k / n - ch["p_pc_lh"]) < 0.015 and abs(either / n - ch["p_pc_either"]) < 0.015, (k, either, n)


def test_gestures_and_nods_move_clearly_above_idle(motion_corpus):
    """Planted gestures: hand speed relative to the shoulder peaks well above idle; nods: the forehead
    (the head's End Site) moves a few centimetres vertically."""
    from scipy.spatial.transform import Rotation

    from convsynth_jax.kinematics import global_transforms

    ev = pd.read_csv(motion_corpus / "events.csv")
    for role in ("main-agent", "interloctr"):
        m = load_bvh(motion_corpus / f"session01_{role}.bvh")
        pos, rot = (np.asarray(x, np.float64) for x in global_transforms(m))
        t = np.arange(len(pos)) / m.fps
        e = ev[(ev.session == "session01") & (ev.participant == role)]
        busy = np.zeros(len(t), bool)
        for r in e[e.kind.isin(["LH", "RH", "Nod"])].itertuples():
            busy |= (t >= r.start - 0.2) & (t <= r.end + 0.2)
        names = list(m.skeleton.names)
        for side, kind in (("Left", "LH"), ("Right", "RH")):
            rel = pos[:, names.index(f"{side}Hand")] - pos[:, names.index(f"{side}Shoulder")]
            speed = np.linalg.norm(np.gradient(rel, axis=0), axis=1) * m.fps
            idle = np.percentile(speed[~busy], 95)
            assert 0.2 < idle < 15.0  # never perfectly still, but calm (cm/s)
            for r in e[e.kind == kind].itertuples():
                inside = (t >= r.start) & (t <= r.end)
                assert speed[inside].max() > 3 * idle, (role, kind, r.start)
        head = names.index("Head")
        tip = pos[:, head] + Rotation.from_quat(rot[:, head][:, [1, 2, 3, 0]]).apply(dict(m.skeleton.end_sites)[head])
        for r in e[e.kind == "Nod"].itertuples():
            inside = (t >= r.start) & (t <= r.end)
            assert 1.0 < np.ptp(tip[inside, 1]) < 8.0, (role, r.start)


def test_praat_finds_the_planted_accent_peaks():
    """The clause's F0 maximum measured by Praat lies at the planted peak (the stressed word)."""
    import parselmouth

    from convsynth_jax.data.synthetic import _conversation, _render_voice

    cfg = resolve_config({})
    rng = np.random.default_rng(7)
    segs = _conversation(rng, cfg, 30.0, 1.0)
    own = [s for s in segs if s.role == "main-agent"]
    sig, _ = _render_voice(own, 210.0, 30.0, 16000, rng, cfg["accent_rise"])
    pitch = parselmouth.Sound(sig, 16000).to_pitch(time_step=0.01, pitch_floor=75, pitch_ceiling=500)
    t, f = pitch.xs(), pitch.selected_array["frequency"]
    pcs = [s for s in own if s.kind == "PC"]
    assert len(pcs) >= 3
    for s in pcs:
        inside = (t >= s.start) & (t <= s.end) & (f > 0)
        assert abs(t[inside][np.argmax(f[inside])] - s.peak) < 0.05


def test_ensure_reuses_or_regenerates(tmp_path):
    corpus_cfg = {"name": "syn", "root": None, "generator": {**SMALL, "num_sessions": 1, "write_audio": False}}
    root = ensure_synthetic_corpus(corpus_cfg, tmp_path)
    assert root == tmp_path / "syn" and (root / "corpus.json").is_file()
    stamp = (root / "corpus.json").stat().st_mtime_ns
    assert ensure_synthetic_corpus(corpus_cfg, tmp_path) == root
    assert (root / "corpus.json").stat().st_mtime_ns == stamp  # reused, not rewritten
    other = {**corpus_cfg, "generator": {**corpus_cfg["generator"], "seed": 4}}
    ensure_synthetic_corpus(other, tmp_path)
    meta = json.loads((root / "corpus.json").read_text())
    assert meta["seed"] == 4 and meta["characters"] == {"main-agent": "female", "interloctr": "male"}
    assert not [p for p in tmp_path.glob(".syn.*") if p.is_dir()]  # no temporary folder left behind (the lock file stays)
