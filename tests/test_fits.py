"""Distribution fits for the transition-cost threshold (stats/fits.py)."""
import numpy as np
import pytest
from scipy import stats

from convsynth_jax.errors import ConfigError, ConvSynthError
from convsynth_jax.stats.fits import CANDIDATES, fit_distributions, johnsonsb_mle


def test_closed_form_johnson_sb_is_the_maximum_likelihood_fit():
    rng = np.random.default_rng(1)
    x = stats.johnsonsb(0.8, 1.3, loc=2.0, scale=50.0).rvs(3000, random_state=rng)
    loc, scale = x.min() - 0.05, x.max() - x.min() + 0.1
    mine = johnsonsb_mle(x, loc, scale)
    numeric = stats.johnsonsb.fit(x, floc=loc, fscale=scale)
    nll = lambda p: -stats.johnsonsb.logpdf(x, *p).sum()  # noqa: E731
    assert nll(mine) <= nll(numeric) + 1e-6
    np.testing.assert_allclose(mine[:2], numeric[:2], rtol=1e-3)
    # perturbing either shape makes the likelihood worse: a maximum
    for d in ((1e-3, 0), (-1e-3, 0), (0, 1e-3), (0, -1e-3)):
        assert nll((mine[0] + d[0], mine[1] + d[1], loc, scale)) > nll(mine)
    with pytest.raises(ValueError):
        johnsonsb_mle(x, x.min(), scale)  # a value on the boundary of the support


@pytest.mark.parametrize("name,dist", [("lognorm", stats.lognorm(0.6, scale=40.0)),
                                       ("gamma", stats.gamma(2.5, scale=7.0)),
                                       ("weibull_min", stats.weibull_min(3.5, scale=20.0))])
def test_auto_choice_finds_the_generating_family(name, dist):
    x = dist.rvs(30000, random_state=np.random.default_rng(2))
    r = fit_distributions(x, choose="auto")
    rss = dict(zip(r.table["distribution"], r.table["rss"]))
    # the generating family wins, or ties with a family that contains it as a limit (Johnson SU
    # holds the lognormal); a wrong family is far worse
    assert r.chosen == name or rss[name] <= 2 * rss[r.chosen], r.table[["distribution", "rss"]]
    assert rss["expon"] > 10 * rss[name]
    assert r.quantile(0.95) == pytest.approx(dist.ppf(0.95), rel=0.05)


def test_rss_is_pdf_against_normalized_histogram_and_table_is_sorted():
    x = stats.gamma(2.5, scale=4.0).rvs(5000, random_state=np.random.default_rng(3))
    r = fit_distributions(x, bins=40)
    assert list(r.table["rss"]) == sorted(r.table["rss"])
    assert set(r.table["distribution"]) == set(CANDIDATES)
    density, edges = np.histogram(x, bins=40, density=True)
    np.testing.assert_allclose(r.density, density)
    centres = (edges[1:] + edges[:-1]) / 2
    for row in r.table.itertuples():
        if np.isfinite(row.rss):
            pdf = getattr(stats, row.distribution).pdf(centres, *row.params)
            assert row.rss == pytest.approx(np.sum((pdf - density) ** 2), rel=1e-9)


def test_forced_choice_and_threshold_is_the_fitted_quantile():
    x = stats.gamma(2.0, scale=3.0).rvs(8000, random_state=np.random.default_rng(4))
    r = fit_distributions(x, choose="johnsonsb")  # the default, even where it is not the best fit
    assert r.chosen == "johnsonsb"
    frozen = stats.johnsonsb(*r.params)
    assert r.quantile(0.95) == pytest.approx(frozen.ppf(0.95))
    # the chosen fit describes the data: its 95% quantile is near the empirical one
    assert r.quantile(0.95) == pytest.approx(np.quantile(x, 0.95), rel=0.08)
    assert r.quantile(0.9) < r.quantile(0.95) < r.quantile(0.99)


def test_bad_inputs():
    with pytest.raises(ConfigError, match="graph.distribution"):
        fit_distributions(np.arange(100.0) + 1, choose="cauchy")
    with pytest.raises(ConvSynthError, match="at least 10"):
        fit_distributions(np.array([1.0, 2.0, np.nan]))
    # determinism: same seed, same fit
    x = stats.lognorm(0.5).rvs(30000, random_state=np.random.default_rng(5))
    assert fit_distributions(x, seed=3).table.equals(fit_distributions(x, seed=3).table)
