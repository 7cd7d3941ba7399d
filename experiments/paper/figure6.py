"""Figure 6: stacked bars of forced-choice preferences from a `user_study` task's user_study.csv."""
from _common import done, parse, read_csv

from convsynth_jax.figures import save_figure
from convsynth_jax.figures.motion_graph import figure6_figure

if __name__ == "__main__":
    src, out, t0 = parse(__doc__, "user_study.csv")
    fig = figure6_figure(read_csv(src))
    save_figure(fig, out / "figure6.png", dpi=120)
    save_figure(fig, out / "figure6.pdf", dpi=120)
    done(out, ["figure6.png", "figure6.pdf"], t0)
