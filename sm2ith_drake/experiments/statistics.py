"""Bootstrap confidence intervals for the studies (issue 12): medians per
group and paired differences between methods, both with
``scipy.stats.bootstrap`` (no resampler of our own), and the three-way
verdict the findings table uses.
"""

from __future__ import annotations

import dataclasses
import math
import warnings

import numpy as np
from scipy import stats

CONFIDENCE = 0.95
RESAMPLES = 2000
# Fewer samples (or pairs) than this get no interval: a bootstrap of two or
# three values says little.
MIN_SAMPLES = 5
# A fixed generator seed: a report written twice from the same CSV says the
# same.
_SEED = 12

HOLDS = "holds"
DOES_NOT_HOLD = "does not hold"
NOT_DISTINGUISHABLE = "not distinguishable"


@dataclasses.dataclass(frozen=True)
class Estimate:
    """A statistic with its bootstrap CI (low, high) over n samples (or
    pairs). With n < MIN_SAMPLES the interval is NaN."""

    value: float
    low: float
    high: float
    n: int

    def Format(self, digits: int = 3, *, with_n: bool = False) -> str:
        """ "value [low, high]", with " (n=…)" if asked for or without an
        interval."""
        if self.n == 0:
            return "–"
        v = f"{self.value:.{digits}g}"
        if math.isnan(self.low):
            return f"{v} (n={self.n})"
        ci = f"{v} [{self.low:.{digits}g}, {self.high:.{digits}g}]"
        return f"{ci} (n={self.n})" if with_n else ci


def _Bootstrap(data, statistic, *, paired: bool) -> tuple[float, float]:
    with warnings.catch_warnings():
        # All-equal samples are "degenerate": the percentile interval is
        # then the point itself, which is what we want to show.
        warnings.simplefilter("ignore")
        result = stats.bootstrap(
            data,
            statistic,
            paired=paired,
            vectorized=True,
            n_resamples=RESAMPLES,
            confidence_level=CONFIDENCE,
            method="percentile",
            rng=np.random.default_rng(_SEED),
        )
    ci = result.confidence_interval
    return float(ci.low), float(ci.high)


def _Median(x, axis=-1):
    return np.median(x, axis=axis)


def _MeanDifference(a, b, axis=-1):
    return np.mean(a - b, axis=axis)


def MedianCI(values) -> Estimate:
    """The median of ``values`` (NaNs dropped) with its percentile bootstrap
    95 % CI (none below MIN_SAMPLES values)."""
    x = np.asarray(values, dtype=float)
    x = x[~np.isnan(x)]
    if x.size == 0:
        return Estimate(math.nan, math.nan, math.nan, 0)
    if x.size < MIN_SAMPLES:
        return Estimate(float(np.median(x)), math.nan, math.nan, int(x.size))
    low, high = _Bootstrap((x,), _Median, paired=False)
    return Estimate(float(np.median(x)), low, high, int(x.size))


def PairedDifference(a, b) -> Estimate:
    """The mean of the paired differences a_i − b_i (pairs with a NaN
    dropped) with its paired percentile bootstrap 95 % CI (none below
    MIN_SAMPLES pairs): pairs are resampled together, so what the pair
    shares (the seed's people) cancels.

    The mean rather than the median: many of our metrics are 0 in most runs
    (intimate-space time, freezing) or booleans (success), where a median
    difference is 0 whatever happens in the other runs.
    """
    a = np.asarray(a, dtype=float)
    b = np.asarray(b, dtype=float)
    if a.shape != b.shape:
        raise ValueError(f"paired samples differ in length: {a.shape} vs {b.shape}")
    keep = ~(np.isnan(a) | np.isnan(b))
    a, b = a[keep], b[keep]
    if a.size == 0:
        return Estimate(math.nan, math.nan, math.nan, 0)
    value = float(np.mean(a - b))
    if a.size < MIN_SAMPLES:
        return Estimate(value, math.nan, math.nan, int(a.size))
    low, high = _Bootstrap((a, b), _MeanDifference, paired=True)
    return Estimate(value, low, high, int(a.size))


def Verdict(differences, *, lower_is_better: bool) -> str:
    """The three-way verdict on "the method is better than each other":
    holds when every difference's CI lies strictly on the better side of 0,
    does not hold when some CI lies strictly on the other side, otherwise
    (an interval spans 0, or is missing) not distinguishable at this
    sample size."""
    sign = -1.0 if lower_is_better else 1.0
    better = []
    for d in differences:
        if d.n < MIN_SAMPLES or math.isnan(d.low):
            better.append(None)
        elif sign * d.low > 0 and sign * d.high > 0:
            better.append(True)
        elif sign * d.low < 0 and sign * d.high < 0:
            better.append(False)
        else:
            better.append(None)
    if any(b is False for b in better):
        return DOES_NOT_HOLD
    if better and all(b is True for b in better):
        return HOLDS
    return NOT_DISTINGUISHABLE
