"""Success rate per ablation condition from collected leave-one-out cases (paper Section 8.1:
69.8% with all constraints, 86.2% without HP)."""
from _common import done, parse, read_csv

from convsynth_jax.evaluation import summaries
from convsynth_jax.figures import save_figure
from convsynth_jax.figures.motion_graph import success_rate_figure

if __name__ == "__main__":
    src, out, t0 = parse(__doc__, "all_cases.csv")
    cases = read_csv(src)
    cases = cases[cases.get("status", "ok") != "error"] if "status" in cases else cases
    table = summaries.success_rates(cases)
    table.to_csv(out / "success_rates.csv", index=False)
    (out / "success_rates.md").write_text(summaries.to_markdown(table))
    fig = success_rate_figure(table)
    save_figure(fig, out / "success_rates.png", dpi=120)
    save_figure(fig, out / "success_rates.pdf", dpi=120)
    done(out, ["success_rates.csv", "success_rates.md", "success_rates.png", "success_rates.pdf"], t0)
