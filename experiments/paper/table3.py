"""Table 3: mean and standard deviation of graph construction and search time, from collected
leave-one-out cases (paper: 47.94 +- 3.30 s construction, 1.16 +- 0.56 s search, 4 cores)."""
from _common import done, parse, read_csv

from convsynth_jax.evaluation import summaries

if __name__ == "__main__":
    src, out, t0 = parse(__doc__, "all_cases.csv")
    table = summaries.timing_table(read_csv(src))
    table.to_csv(out / "table3.csv", index=False)
    (out / "table3.md").write_text(summaries.to_markdown(table))
    done(out, ["table3.csv", "table3.md"], t0)
