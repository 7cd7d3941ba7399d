"""Table 1: audio-motion co-occurrence per character and hypothesis, from a `cooccurrence.csv`
written by `convsynth task=cooccurrence` (or `table1_cooccurrence.csv` of a main run).
Writes Markdown, LaTeX and a bar chart next to the chance rates."""
import sys

from _common import done, parse, read_csv

from convsynth_jax.evaluation import summaries

if __name__ == "__main__":
    name = "cooccurrence.csv"
    if len(sys.argv) > 1 and not sys.argv[1].endswith(".csv"):
        from pathlib import Path

        if (Path(sys.argv[1]) / "table1_cooccurrence.csv").is_file() and not (Path(sys.argv[1]) / name).is_file():
            name = "table1_cooccurrence.csv"
    src, out, t0 = parse(__doc__, name)
    t = read_csv(src)
    cols = [c for c in ("character", "hypothesis", "matched", "total", "rate", "ci_low", "ci_high", "chance_method",
                        "chance_rate", "chi2", "df", "p_chi2", "p_permutation") if c in t]
    table = t[cols].copy()
    for c in ("rate", "ci_low", "ci_high"):
        if c in table:
            table[c] = (100 * table[c]).round(1)
    if "chance_rate" in table:
        table["chance_rate"] = (100 * table["chance_rate"]).round(1)
    (out / "table1.md").write_text(summaries.to_markdown(table))
    (out / "table1.tex").write_text(summaries.to_latex(table))

    from convsynth_jax.figures import save_figure
    from convsynth_jax.figures.motion_graph import table1_figure

    fig = table1_figure(t if "chance_rate" in t else t.assign(chance_rate=float("nan")))
    save_figure(fig, out / "table1.png", dpi=120)
    done(out, ["table1.md", "table1.tex", "table1.png"], t0)
