"""Figure 4: redraw the cost histograms with fitted curves from a `figure4` task's CSVs."""
import pandas as pd
from _common import done, parse

from convsynth_jax.figures import save_figure
from convsynth_jax.figures.motion_graph import figure4_figure

if __name__ == "__main__":
    src, out, t0 = parse(__doc__, "figure4_histograms.csv")
    hist = pd.read_csv(src)
    fits = pd.read_csv(src.parent / "figure4_fits.csv")
    fig = figure4_figure(hist, fits)
    save_figure(fig, out / "figure4.png", dpi=120)
    save_figure(fig, out / "figure4.pdf", dpi=120)
    done(out, ["figure4.png", "figure4.pdf"], t0)
