"""Table 2: states and edges before/after SCC per k, from a `table2` task's table2.csv."""
from _common import done, parse, read_csv

from convsynth_jax.evaluation import summaries

if __name__ == "__main__":
    src, out, t0 = parse(__doc__, "table2.csv")
    t = read_csv(src)
    (out / "table2.md").write_text(summaries.to_markdown(t))
    (out / "table2.tex").write_text(summaries.to_latex(t))
    done(out, ["table2.md", "table2.tex"], t0)
