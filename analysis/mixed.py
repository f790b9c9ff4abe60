"""A random-intercept logistic model of the judgments: a sensitivity analysis beside the run-level GEE.

Run i's judgments are k_i yes of n_i with logit P(yes) = x_i' beta + sd u_i, u_i ~ N(0, 1) independent between runs.
Its coefficients are run-specific (conditional) log-odds, larger in size than the GEE's population-averaged ones
when the run SD is above zero. The fit is maximum likelihood, the marginal likelihood of each run integrated over
u_i by adaptive Gauss-Hermite quadrature (numpy's hermgauss nodes centred on the mode of the run's integrand and
scaled by its curvature) and maximised with scipy.optimize over beta and log sd. lme4's glmer(nAGQ = nodes)
fits the same model; its default (nAGQ = 1) is the coarser Laplace approximation. statsmodels' mixed GLM
(BinomialBayesMixedGLM) is Bayesian, a variational or Laplace posterior rather than this likelihood, which is why
the model is written out here.

The run SD can be estimated at 0 (the random intercept adds nothing to the plain logistic fit); it is then
reported as 0 with a note, as lme4 reports a singular fit, and the fit is the ordinary logistic regression.
Parameters get Wald z tests and intervals; each term a likelihood-ratio chi-square test of dropping it.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
from numpy.polynomial.hermite import hermgauss
from scipy.optimize import minimize
from scipy.special import expit, gammaln, logsumexp
from scipy.stats import chi2, norm
from statsmodels.tools.numdiff import approx_fprime

from analysis.models import DesignMatrix, Fit, effect_tests, estimability_notes, estimable_columns, parameter_rows, separation, with_intervals

#: Quadrature nodes per run. With a run SD of 1.6 (tests/test_analysis_mixed.py) the log-likelihood with 10 nodes is
#: 2e-4 from its limit, with 20 2e-7, with 30 1.3e-9.
NODES = 30
#: A random intercept that raises the log-likelihood by less than this over the plain logistic fit is reported as 0.
_BOUNDARY_GAIN = 1e-6
_Z95 = float(norm.ppf(0.975))


def log_likelihood(x: np.ndarray, successes: np.ndarray, trials: np.ndarray, beta: np.ndarray, sd: float, nodes: int = NODES) -> float:
    """The marginal log-likelihood of the runs (binomial coefficients included) at `beta` and run SD `sd` >= 0."""
    return _quadrature(x, successes, trials, beta, sd, nodes)[0]


def _quadrature(x: np.ndarray, successes: np.ndarray, trials: np.ndarray, beta: np.ndarray, sd: float, nodes: int) -> tuple[float, np.ndarray, float]:
    """The marginal log-likelihood and its gradient in beta and in sd. The gradient is the same quadrature applied to
    the conditional score, k - n p weighted by the integrand at each node: the derivative of the integral itself
    (the nodes' dependence on the mode changes the rule, not the integral, so it only moves quadrature error)."""
    eta = x @ beta
    log_choose = gammaln(trials + 1.0) - gammaln(successes + 1.0) - gammaln(trials - successes + 1.0)
    mode, spread = _modes(eta, successes, trials, sd)
    t, w = hermgauss(nodes)
    u = mode[:, None] + math.sqrt(2.0) * spread[:, None] * t[None, :]
    linear = eta[:, None] + sd * u
    terms = _log_integrand(linear, successes[:, None], trials[:, None], u) + t**2 + np.log(w)
    per_run = logsumexp(terms, axis=1)
    weights = np.exp(terms - per_run[:, None])
    score = weights * (successes[:, None] - trials[:, None] * expit(linear))
    value = float(np.sum(log_choose + np.log(math.sqrt(2.0) * spread) + per_run))
    return value, x.T @ score.sum(axis=1), float(np.sum(score * u))


def _log_integrand(linear: np.ndarray, successes: np.ndarray, trials: np.ndarray, u: np.ndarray) -> np.ndarray:
    """log of p^k (1 - p)^(n - k) phi(u) at logit p = `linear`."""
    return -successes * np.logaddexp(0.0, -linear) - (trials - successes) * np.logaddexp(0.0, linear) - 0.5 * u**2 - 0.5 * math.log(2.0 * math.pi)


def _modes(eta: np.ndarray, successes: np.ndarray, trials: np.ndarray, sd: float) -> tuple[np.ndarray, np.ndarray]:
    """Each run's mode of its log integrand in u and the integrand's spread there, (-second derivative)^-1/2.

    The log integrand is strictly concave, its derivative sd (k - n p) - u falls from >= 0 at sd (k - n) to <= 0 at
    sd k, so Newton steps kept inside that shrinking bracket (bisecting when one would leave it) find the root."""
    low, high = sd * (successes - trials), sd * successes
    u = np.clip(np.zeros_like(eta), low, high)
    for _ in range(200):
        p = expit(eta + sd * u)
        slope = sd * (successes - trials * p) - u
        curvature = sd**2 * trials * p * (1.0 - p) + 1.0
        low, high = np.where(slope > 0.0, u, low), np.where(slope < 0.0, u, high)
        step = u + slope / curvature
        step = np.where((step <= low) | (step >= high), 0.5 * (low + high), step)
        done = np.max(np.abs(step - u), initial=0.0) < 1e-13
        u = step
        if done:
            break
    p = 1.0 / (1.0 + np.exp(-(eta + sd * u)))
    return u, 1.0 / np.sqrt(sd**2 * trials * p * (1.0 - p) + 1.0)


def _maximise(objective: Callable[[np.ndarray], tuple[float, np.ndarray]], start: np.ndarray) -> tuple[np.ndarray, float]:
    """The maximum of a smooth `objective` (value and gradient) from `start`: scipy's BFGS, then Newton steps on the
    central-difference derivative of the gradient while they raise the objective, to bring the gradient to ~0."""
    result = minimize(lambda v: tuple(-part for part in objective(v)), start, jac=True, method="BFGS", options={"gtol": 1e-8})
    theta, value = np.asarray(result.x), -float(result.fun)
    for _ in range(5):
        gradient = objective(theta)[1]
        if np.max(np.abs(gradient)) < 1e-9:
            break
        hessian = _hessian(objective, theta)
        if np.any(np.linalg.eigvalsh(hessian) >= 0.0):
            break
        candidate = theta - np.linalg.solve(hessian, gradient)
        if objective(candidate)[0] <= value:
            break
        theta, value = candidate, objective(candidate)[0]
    return theta, value


def _hessian(objective: Callable[[np.ndarray], tuple[float, np.ndarray]], theta: np.ndarray) -> np.ndarray:
    """The Hessian as the central-difference derivative of the gradient (statsmodels' numdiff), symmetrized."""
    hessian = approx_fprime(theta, lambda v: objective(v)[1], centered=True)
    return 0.5 * (hessian + hessian.T)


def _plain(x: np.ndarray, successes: np.ndarray, trials: np.ndarray, nodes: int) -> Callable[[np.ndarray], tuple[float, np.ndarray]]:
    """The log-likelihood with the run SD at 0, as a function of beta."""
    def objective(beta: np.ndarray) -> tuple[float, np.ndarray]:
        value, gradient, _ = _quadrature(x, successes, trials, beta, 0.0, nodes)
        return value, gradient
    return objective


def _random(x: np.ndarray, successes: np.ndarray, trials: np.ndarray, nodes: int) -> Callable[[np.ndarray], tuple[float, np.ndarray]]:
    """The log-likelihood as a function of (beta, log sd)."""
    def objective(theta: np.ndarray) -> tuple[float, np.ndarray]:
        sd = math.exp(theta[-1])
        value, gradient, d_sd = _quadrature(x, successes, trials, theta[:-1], sd, nodes)
        return value, np.r_[gradient, d_sd * sd]
    return objective


def _fit(x: np.ndarray, successes: np.ndarray, trials: np.ndarray, nodes: int) -> tuple[np.ndarray, float, float]:
    """Maximum-likelihood beta, run SD and log-likelihood: the plain logistic fit (SD 0) unless the random intercept,
    sought from starting SDs 0.5 and 2, raises the log-likelihood by at least _BOUNDARY_GAIN."""
    beta, plain = _maximise(_plain(x, successes, trials, nodes), np.zeros(x.shape[1]))
    fits = [_maximise(_random(x, successes, trials, nodes), np.r_[beta, math.log(start)]) for start in (0.5, 2.0)]
    theta, value = max(fits, key=lambda fit: fit[1])
    if value - plain < _BOUNDARY_GAIN:
        return beta, 0.0, plain
    return theta[:-1], math.exp(theta[-1]), value


def fit_mixed(dm: DesignMatrix, successes: np.ndarray, trials: np.ndarray, response: str, nodes: int = NODES) -> Fit:
    """The random-intercept logistic model of `successes` of `trials` per run (rows of `dm`) by maximum likelihood."""
    successes = np.asarray(successes, dtype=float)
    trials = np.asarray(trials, dtype=float)
    judged = trials > 0
    keep = estimable_columns(dm.x[judged])
    notes = estimability_notes(dm, keep, int(judged.sum()))
    x, k, n = dm.x[judged][:, keep], successes[judged], trials[judged]
    method = f"logistic mixed model, random intercept per run (maximum likelihood, adaptive Gauss-Hermite quadrature with {nodes} nodes)"
    test = "likelihood-ratio chi-square"
    missing = np.full(x.shape[1], math.nan)
    empty = Fit(response, method, len(trials), int(trials.sum()), "z", test, parameter_rows(dm, keep, missing, missing, missing, missing), [], notes)
    if len(k) == 0:
        notes.append("No run has judgments: nothing to fit.")
        return empty
    if separation(x, k, n) is not None:
        notes.append("The judgments are perfectly separated: the mixed model's maximum-likelihood estimates do not exist.")
        return empty
    beta, sd, value = _fit(x, k, n, nodes)
    p = len(beta)
    if sd == 0.0:
        notes.append(
            "The run SD is estimated at 0 (a singular fit, as lme4 would say): the random intercept adds nothing, "
            "so the fit is the plain logistic regression."
        )
        hessian = _hessian(_plain(x, k, n, nodes), beta)
    else:
        hessian = _hessian(_random(x, k, n, nodes), np.r_[beta, math.log(sd)])
    se = np.sqrt(np.diag(np.linalg.inv(-hessian)))[:p]
    z = beta / se
    parameters = parameter_rows(dm, keep, beta, se, z, 2.0 * norm.sf(np.abs(z)))
    parameters = with_intervals(parameters, keep, list(zip(beta - _Z95 * se, beta + _Z95 * se)))
    position = np.cumsum(keep) - 1  # column of dm -> its index among the kept columns

    def likelihood_ratio(remaining: np.ndarray, df: int) -> tuple[float, float]:
        kept = [int(position[j]) for j in remaining]
        statistic = max(0.0, 2.0 * (value - _fit(x[:, kept], k, n, nodes)[2]))
        return statistic, float(chi2.sf(statistic, df))

    effects = effect_tests(dm, keep, likelihood_ratio)
    summary = {"run SD": sd, "log-likelihood": value}
    return Fit(response, method, len(trials), int(trials.sum()), "z", test, parameters, effects, notes, summary)
