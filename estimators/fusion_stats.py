"""Chi-square quantiles for gating and consistency checks (no scipy: it is not a dependency).

``chi2_cdf(x, k)`` for integer degrees of freedom ``k`` uses the closed forms
    k = 1:  P(1, x) = erf(sqrt(x / 2))
    k = 2:  P(2, x) = 1 - exp(-x / 2)
and the recurrence of the regularised incomplete gamma function
    P(k + 2, x) = P(k, x) - (x / 2)^(k / 2) exp(-x / 2) / Gamma(k / 2 + 1),
evaluated in log space. For large ``k`` (> 200) the Wilson-Hilferty cube-root normal approximation
is used (relative quantile error < 1e-4 there). ``chi2_ppf`` inverts the CDF by bisection.
``cluster_mean_interval`` is a cluster (whole-track) bootstrap interval of a pooled mean.
"""

from __future__ import annotations

import math
from collections.abc import Hashable, Sequence

import numpy as np

from estimators.errors import InputError

__all__ = ["CLUSTER_MIN", "chi2_cdf", "chi2_ppf", "cluster_mean_interval", "median_variance_factor",
           "nees_interval", "normal_ppf"]

_WH_MIN_DOF = 200


def _check_dof(k: int) -> int:
    if int(k) != k or k < 1:
        raise InputError(f"chi2: expected a positive integer number of degrees of freedom, got {k!r}")
    return int(k)


def normal_ppf(p: float) -> float:
    """Quantile of the standard normal distribution (bisection on ``erf``), p in (0, 1)."""
    if not 0.0 < p < 1.0:
        raise InputError(f"normal_ppf: expected a probability in (0, 1), got {p!r}")
    lo, hi = -40.0, 40.0
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        if 0.5 * (1.0 + math.erf(mid / math.sqrt(2.0))) < p:
            lo = mid
        else:
            hi = mid
    return 0.5 * (lo + hi)


def chi2_cdf(x: float, k: int) -> float:
    """P(X <= x) for X ~ chi-square with ``k`` (integer >= 1) degrees of freedom."""
    k = _check_dof(k)
    if x <= 0.0:
        return 0.0
    if k > _WH_MIN_DOF:  # Wilson-Hilferty: (X/k)^(1/3) ~ N(1 - 2/(9k), 2/(9k))
        m = 1.0 - 2.0 / (9.0 * k)
        s = math.sqrt(2.0 / (9.0 * k))
        z = ((x / k) ** (1.0 / 3.0) - m) / s
        return 0.5 * (1.0 + math.erf(z / math.sqrt(2.0)))
    h = 0.5 * x
    if k % 2 == 1:
        p = math.erf(math.sqrt(h))  # P(1, x)
        a = 0.5
    else:
        p = -math.expm1(-h)  # P(2, x)
        a = 1.0
    # raise a = k0/2 to k/2 in steps of 1: P(a + 1) = P(a) - h^a e^-h / Gamma(a + 1)
    while a < 0.5 * k - 1e-9:
        p -= math.exp(a * math.log(h) - h - math.lgamma(a + 1.0))
        a += 1.0
    return min(max(p, 0.0), 1.0)


def chi2_ppf(prob: float, k: int) -> float:
    """Quantile x with P(X <= x) = ``prob`` for chi-square with ``k`` degrees of freedom."""
    k = _check_dof(k)
    if not 0.0 < prob < 1.0:
        raise InputError(f"chi2_ppf: expected a probability in (0, 1), got {prob!r}")
    if k > _WH_MIN_DOF:
        z = normal_ppf(prob)
        m = 1.0 - 2.0 / (9.0 * k)
        return k * (m + z * math.sqrt(2.0 / (9.0 * k))) ** 3
    lo, hi = 0.0, max(10.0, 10.0 * k)
    while chi2_cdf(hi, k) < prob:
        hi *= 2.0
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        if chi2_cdf(mid, k) < prob:
            lo = mid
        else:
            hi = mid
        if hi - lo < 1e-12 * max(1.0, hi):
            break
    return 0.5 * (lo + hi)


def nees_interval(dof: int, n_runs: int, prob: float = 0.95) -> tuple[float, float]:
    """Two-sided ``prob`` interval of the mean of ``n_runs`` independent chi-square(``dof``) samples.

    n * mean ~ chi-square(n * dof), so the interval is [chi2_ppf(a, n dof), chi2_ppf(1 - a, n dof)] / n
    with a = (1 - prob) / 2 (Bar-Shalom, Li, Kirubarajan 2001, sec. 5.4.2).
    """
    if n_runs < 1:
        raise InputError(f"nees_interval: expected n_runs >= 1, got {n_runs}")
    a = 0.5 * (1.0 - prob)
    kk = _check_dof(dof) * int(n_runs)
    return chi2_ppf(a, kk) / n_runs, chi2_ppf(1.0 - a, kk) / n_runs


# the ends' standard deviation over seeds <= 0.0008 on the accuracy sets' range NEES (tuned, held-out, demo,
# highfps; at 1e5 up to 0.004, highfps's upper end)
CLUSTER_RESAMPLES = 400_000
# below this many clusters a cluster-bootstrap interval tends to come out too narrow (Cameron, Gelbach and
# Miller 2008): shown, but not read as "1.0 inside / outside"
CLUSTER_MIN = 30
_RESAMPLE_CHUNK = 1 << 17  # drawn cluster indices per chunk


def cluster_mean_interval(values: Sequence[float], clusters: Sequence[Hashable], prob: float = 0.95,
                          n_resamples: int = CLUSTER_RESAMPLES,
                          seed: int = 0) -> tuple[float, float] | None:
    """Two-sided ``prob`` interval of the pooled mean of ``values`` that respects correlation
    within clusters: ``clusters[i]`` names the cluster (e.g. the (scene, track) of a report) of
    ``values[i]``; values of one cluster may be correlated, clusters are taken as independent.

    Cluster bootstrap (Davison and Hinkley 1997, Bootstrap Methods and their Application, sec. 3.8:
    resample the top-level units; Field and Welsh 2007, JRSS B 69(3), "Bootstrapping clustered
    data"): ``n_resamples`` times, draw as many clusters as there are, with replacement, and take the
    pooled mean of every value of the drawn clusters (sum of their values / their count, so a long
    cluster weighs as much as its values do in the mean itself); the interval is the
    (1 - prob) / 2 and (1 + prob) / 2 quantiles of those means (percentile interval, Efron and
    Tibshirani 1993, ch. 13). Seeded: the same input gives the same interval.

    None with fewer than two clusters (no spread between clusters to resample); InputError for
    values and clusters of different lengths, a non-finite value or ``prob`` outside (0, 1). With few
    clusters (Cameron, Gelbach and Miller 2008: below ~30) the interval tends to be too narrow."""
    v = np.asarray(values, dtype=float).ravel()
    if len(v) != len(clusters):
        raise InputError(f"cluster_mean_interval: expected one cluster per value, got {len(v)} values "
                         f"and {len(clusters)} clusters")
    if not np.all(np.isfinite(v)):
        raise InputError(f"cluster_mean_interval: expected finite values, got {int((~np.isfinite(v)).sum())} "
                         "NaN or infinite")
    if not 0.0 < prob < 1.0:
        raise InputError(f"cluster_mean_interval: expected a probability in (0, 1), got {prob!r}")
    if int(n_resamples) != n_resamples or n_resamples < 1:
        raise InputError(f"cluster_mean_interval: expected n_resamples >= 1, got {n_resamples!r}")
    ids: dict = {}
    idx = np.array([ids.setdefault(c, len(ids)) for c in clusters], dtype=np.int64)
    k = len(ids)
    if k < 2:
        return None
    sums = np.bincount(idx, weights=v, minlength=k)
    counts = np.bincount(idx, minlength=k).astype(float)
    rng = np.random.default_rng(seed)
    means = np.empty(int(n_resamples))
    rows = max(1, _RESAMPLE_CHUNK // k)
    for i in range(0, len(means), rows):
        pick = rng.integers(0, k, size=(min(rows, len(means) - i), k))
        means[i:i + len(pick)] = sums[pick].sum(axis=1) / counts[pick].sum(axis=1)
    a = 0.5 * (1.0 - prob)
    lo, hi = np.quantile(means, [a, 1.0 - a])
    return float(lo), float(hi)


# n Var(median) / sigma^2 of n independent normal samples (even n: the mean of the two middle ones,
# as np.median), n = 2..16: Monte Carlo, 2e6 draws per n (+-0.002); n = 2 is exactly 1 (the mean) and
# n = 3 is 3 x 0.4487, the variance of the middle order statistic of three (David and Nagaraja 2003,
# Order Statistics, 3rd ed.). It tends to pi / 2 (odd n from below, even n more slowly).
_MEDIAN_VAR = (1.0, 1.346, 1.191, 1.433, 1.289, 1.475, 1.343, 1.496, 1.384, 1.509, 1.411, 1.517, 1.430,
               1.525, 1.447)


def median_variance_factor(n: int) -> float:
    """c_n = n Var(median) / sigma^2 for the median of n >= 1 independent normal samples of variance
    sigma^2 (so Var(median) = c_n sigma^2 / n); pi / 2 (the large-n limit, an upper bound within 9 %)
    beyond n = 16."""
    if int(n) != n or n < 1:
        raise InputError(f"median_variance_factor: expected a sample count n >= 1, got {n!r}")
    n = int(n)
    if n == 1:
        return 1.0
    return _MEDIAN_VAR[n - 2] if n - 2 < len(_MEDIAN_VAR) else math.pi / 2.0

