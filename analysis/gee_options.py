"""How the run-level GEE (`analysis.clustered`) is fitted and tested: its conventions, as the analysis plan names them.

Kept apart from the fit so that reading or writing an analysis plan does not import statsmodels.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

from analysis.errors import AnalysisError

Covariance = Literal["mancl-derouen", "kauermann-carroll"]
Reference = Literal["t", "z"]
Correlation = Literal["exchangeable", "independence"]
AlphaEstimator = Literal["statsmodels", "geepack"]
#: The small-sample sandwich corrections, and the conventions of the exchangeable correlation's moment estimate.
COVARIANCES: tuple[Covariance, ...] = ("mancl-derouen", "kauermann-carroll")
ALPHA_ESTIMATORS: tuple[AlphaEstimator, ...] = ("statsmodels", "geepack")


@dataclass(frozen=True)
class GeeOptions:
    """How the run-level GEE is fitted and tested; the defaults are the choice valid with few runs."""

    covariance: Covariance = "mancl-derouen"
    reference: Reference = "t"
    correlation: Correlation = "exchangeable"
    alpha_estimator: AlphaEstimator = "statsmodels"

    def __post_init__(self) -> None:
        allowed = {"covariance": COVARIANCES, "reference": ("t", "z"), "correlation": ("exchangeable", "independence"),
                   "alpha_estimator": ALPHA_ESTIMATORS}
        for name, values in allowed.items():
            if getattr(self, name) not in values:
                raise AnalysisError(f"GEE option {name} is {getattr(self, name)!r}; expected one of {', '.join(values)}")

    def method(self, df: int | None) -> str:
        """The method text: each convention in use (`df`: the cluster degrees of freedom, when known)."""
        if self.correlation == "independence":
            correlation = "independence working correlation"
        elif self.alpha_estimator == "geepack":
            correlation = "exchangeable working correlation, moment estimate over all pairs and judgments as geepack's"
        else:
            correlation = "exchangeable working correlation, moment estimate with p subtracted from pairs and judgments as statsmodels'"
        covariance = "Mancl-DeRouen" if self.covariance == "mancl-derouen" else "Kauermann-Carroll"
        if self.reference == "z":
            reference = "z and chi-square references"
        else:
            reference = "t and F references on " + (f"{df} cluster df" if df is not None else "the cluster df")
        return f"logistic GEE clustered by run ({correlation}; {covariance} bias-reduced sandwich errors; {reference})"
