"""Ablation comparison: co-occurrence of gestures/nods with audio in synthesized motion per condition
versus the held-out ground truth (two-sample proportion tests), and motion-quality metrics."""
from _common import done, parse, read_csv

from convsynth_jax.evaluation import summaries
from convsynth_jax.figures import save_figure
from convsynth_jax.figures.motion_graph import ablation_figure

if __name__ == "__main__":
    src, out, t0 = parse(__doc__, "all_cases.csv")
    cases = read_csv(src)
    co = summaries.cooccurrence_by_condition(cases)
    q = summaries.quality_by_condition(cases)
    co.to_csv(out / "ablation_cooccurrence.csv", index=False)
    q.to_csv(out / "ablation_quality.csv", index=False)
    (out / "ablation.md").write_text("## Co-occurrence\n\n" + summaries.to_markdown(co)
                                     + "\n## Motion quality\n\n" + summaries.to_markdown(q))
    fig = ablation_figure(co)
    save_figure(fig, out / "ablation.png", dpi=120)
    save_figure(fig, out / "ablation.pdf", dpi=120)
    done(out, ["ablation_cooccurrence.csv", "ablation_quality.csv", "ablation.md", "ablation.png"], t0)
