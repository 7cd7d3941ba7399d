"""Benchmark: drawing and encoding ``conversation.mp4`` (convsynth_jax/render/, docs/render.md).

Input: a ``task=converse`` output folder (``--folder``), or, without one, the converse benchmark's
timing input (``bench_converse.speech_inputs``: the shared recordings repeated to ``--seconds`` as
A, B silent) run once through ``task=converse`` with ``task.video=false`` (models from
``$CONVSYNTH_CACHE``). Then ``tasks.converse.render_conversation``'s drawing is timed ``--repeats``
times: the frames alone (wall and CPU seconds), and the whole video with the audio (wall, this
process's CPU, ffmpeg's CPU). The goal (docs/converse.md): about 4-7 s of video for 60 s of speech.

    python experiments/bench/bench_render.py [--folder OUT] [--seconds 60] [--repeats 3] [--fps 10]
"""
import argparse
import json
import os
import resource
import statistics
import sys
import tempfile
import time
from pathlib import Path

from convsynth_jax.api import run_convsynth, write_result



def _cpu(who) -> float:
    r = resource.getrusage(who)
    return r.ru_utime + r.ru_stime


def converse_output(seconds: float, work: Path) -> Path:
    """A task=converse output (no video) of the timing input, in ``work``."""
    from bench_converse import speech_inputs

    over, _ = speech_inputs(work, seconds)
    out = work / "out"
    run_convsynth(["task=converse", *[f"{k}={v}" for k, v in over.items()], "task.video=false", "progress=false"], out).check()
    return out


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--folder", type=Path, default=None)
    ap.add_argument("--seconds", type=float, default=60.0)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--fps", type=float, default=10.0)
    a = ap.parse_args()

    import pandas as pd

    from convsynth_jax import render as R
    from convsynth_jax.io import load_bvh

    with tempfile.TemporaryDirectory() as tmp:
        folder = a.folder or converse_output(a.seconds, Path(tmp))
        rep = json.loads((folder / "report.json").read_text())
        motions = {w: load_bvh(folder / f"{w}.bvh") for w in "AB"}
        fps = float(motions["A"].fps)
        names = [f"{w} ({rep['characters'][w]['character']})" for w in "AB"]
        bodies = tuple(R.body_from_motion(motions[w], names[k]) for k, w in enumerate("AB"))
        lines = [R.Timeline(names[k], pd.DataFrame(rep["segments"][w], columns=["kind", "start", "end"]),
                            tuple(t["frame"] / fps for t in rep["characters"][w].get("transitions", [])), k)
                 for k, w in enumerate("AB")]
        panels = [R.Panel(f"{names[0]} and {names[1]}", bodies)]
        step = max(1, int(round(fps / a.fps)))
        runs = []
        for _ in range(a.repeats):
            load = os.getloadavg()[0]
            c, t = _cpu(resource.RUSAGE_SELF), time.perf_counter()
            r = R.FrameRenderer(panels, lines, fps, 640, 360)
            n = sum(1 for _ in r.frames(step))
            draw_wall, draw_cpu = time.perf_counter() - t, _cpu(resource.RUSAGE_SELF) - c
            c, k, t = _cpu(resource.RUSAGE_SELF), _cpu(resource.RUSAGE_CHILDREN), time.perf_counter()
            R.render_video(panels, lines, fps, Path(tmp) / "conversation.mp4", audio=folder / "conversation.wav",
                           render_fps=a.fps, panel_width=640, panel_height=360)
            runs.append({"frames": n, "frame_size": [r.width, r.height], "draw_wall_s": draw_wall, "draw_cpu_s": draw_cpu,
                         "draw_cpu_ms_per_frame": 1000 * draw_cpu / n, "video_wall_s": time.perf_counter() - t,
                         "video_cpu_s": _cpu(resource.RUSAGE_SELF) - c, "ffmpeg_cpu_s": _cpu(resource.RUSAGE_CHILDREN) - k,
                         "bytes": (Path(tmp) / "conversation.mp4").stat().st_size, "load_avg_1min": [load, os.getloadavg()[0]]})
    seconds = bodies[0].num_frames / fps
    result = {"input": str(a.folder) if a.folder else f"bench_converse timing input, {a.seconds:g} s, B silent",
              "seconds_of_motion": seconds, "video_fps": a.fps, "runs": runs,
              "median_video_wall_s": statistics.median(x["video_wall_s"] for x in runs),
              "median_draw_cpu_ms_per_frame": statistics.median(x["draw_cpu_ms_per_frame"] for x in runs),
              "goal": "about 4-7 s of video for 60 s of speech (docs/converse.md)"}
    write_result("bench_render", result, overrides=sys.argv[1:])


if __name__ == "__main__":
    main()
