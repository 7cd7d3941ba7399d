import numpy as np
import pytest
from scipy import stats as sst

from convsynth_jax.stats import chi2_independence, permutation_test, prop_test, proportion_test
from convsynth_jax.stats.fits import fit_distributions

PAPER = [  # (preferred A, total) -> chi2, p as printed in the paper (R's prop.test)
    (64, 206, 57.563, 3.272e-14), (108, 193, 5.0155, 0.02512), (94, 201, 1.4328, 0.2313), (116, 200, 9.61, 0.001935)]


@pytest.mark.parametrize("a,n,chi2,p", PAPER)
def test_proportion_test_reproduces_paper(a, n, chi2, p):
    r = proportion_test(a, n - a, n)
    assert r.df == 1
    assert r.chi2 == pytest.approx(chi2, rel=5e-4)
    assert r.p_value == pytest.approx(p, rel=2e-3)


def test_prop_test_hand_computed_and_uncorrected_matches_pearson():
    # x = (15, 25), n = (50, 50): expected 20/30 per row; |O - E| = 5; Yates: 4.5^2 * (2/20 + 2/30)
    r = prop_test((15, 25), (50, 50))
    assert r.chi2 == pytest.approx(4.5**2 * (2 / 20 + 2 / 30))
    r0 = prop_test((15, 25), (50, 50), correct=False)
    chi2, p, _, _ = sst.chi2_contingency([[15, 35], [25, 25]], correction=False)
    assert r0.chi2 == pytest.approx(chi2) and r0.p_value == pytest.approx(p)
    with pytest.raises(ValueError):
        prop_test((60, 1), (50, 50))


def test_chi2_independence_and_permutation():
    strong = chi2_independence(40, 50, 5, 50)
    assert strong.df == 1 and strong.p_value < 1e-8
    assert chi2_independence(20, 50, 21, 50).p_value > 0.5
    a = np.r_[np.ones(40), np.zeros(10)]
    b = np.r_[np.ones(5), np.zeros(45)]
    assert permutation_test(a, b, 2000) < 0.01
    assert permutation_test(b, a, 2000) > 0.9
    assert permutation_test(a, a.copy(), 2000) > 0.3


def test_fits_recover_the_generating_distribution_and_quantile():
    rng = np.random.default_rng(0)
    x = sst.johnsonsb(1.2, 0.9, loc=0, scale=10).rvs(20000, random_state=rng)
    r = fit_distributions(x, choose="auto")
    assert r.chosen in ("johnsonsb", "beta")  # beta and Johnson SB are both bounded and close here
    assert r.quantile(0.95, "johnsonsb") == pytest.approx(np.quantile(x, 0.95), rel=0.03)
    g = sst.gamma(2.0, scale=3.0).rvs(20000, random_state=rng)
    assert fit_distributions(g, choose="auto").chosen == "gamma"
